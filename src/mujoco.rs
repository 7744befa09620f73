//! The same model in MuJoCo, in process (cargo feature `mujoco`), for the cross-checks and
//! the side-by-side benchmark.
//!
//! The model is exported with [`crate::mjcf::to_mjcf`] (one MuJoCo joint per full
//! coordinate) and loaded into MuJoCo from memory. Quantities are returned in musculo's
//! full-coordinate order, so that they compare directly with `crba_full`, `rnea_full`,
//! body poses and full-coordinate Jacobians.

use crate::error::Error;
use crate::model::Model;
use crate::spatial::{Mat3, Vec3};
use mujoco_rs::mujoco_c as mj;
use mujoco_rs::wrappers::{MjData, MjModel};
use nalgebra::DMatrix;
use std::ffi::CString;

/// The MuJoCo library version linked at run time, as MuJoCo numbers it (3.17.0 → 3017000).
pub fn linked_version() -> u32 {
    // SAFETY: mj_version only reads a constant.
    unsafe { mj::mj_version() as u32 }
}

/// The MuJoCo version mujoco-rs was built for.
pub const EXPECTED_VERSION: u32 = mj::mjVERSION_HEADER;

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", v / 1_000_000, (v / 1000) % 1000, v % 1000)
}

/// Errors (readably, instead of MuJoCo's own abort) unless the linked library is the version
/// the bindings were generated for.
pub fn check_version(linked: u32, expected: u32) -> crate::Result<()> {
    if linked != expected {
        return Err(Error::Mujoco {
            message: format!(
                "the linked MuJoCo library is version {} but musculo was built for {}; \
                 install the matching one with scripts/setup-mujoco.sh",
                version_string(linked),
                version_string(expected)
            ),
        });
    }
    Ok(())
}

/// A musculo model loaded into MuJoCo, with the index maps between the two.
pub struct MujocoTwin {
    data: MjData<Box<MjModel>>,
    nv: usize,
    /// qpos (= qvel) address of each musculo full coordinate.
    adr: Vec<usize>,
    /// MuJoCo body id of each musculo body (0 = world = ground).
    body_id: Vec<usize>,
    dense: Vec<f64>,
    vec: Vec<f64>,
    jacp: Vec<f64>,
    jacr: Vec<f64>,
    /// What the MJCF export could not express (see `MjcfExport::notes`).
    pub notes: Vec<String>,
}

impl MujocoTwin {
    /// Exports `model` to MJCF and loads it into MuJoCo.
    pub fn new(model: &Model) -> crate::Result<MujocoTwin> {
        check_version(linked_version(), EXPECTED_VERSION)?;
        let export = crate::mjcf::to_mjcf(model);
        let mj_model = MjModel::from_xml_string(&export.xml).map_err(|e| Error::Mujoco {
            message: format!("MuJoCo could not load the exported model: {e:?}"),
        })?;
        let m = mj_model.ffi();
        let nv = m.nv as usize;
        if m.nq as usize != model.n_full() || nv != model.n_full() {
            return Err(Error::Mujoco {
                message: format!(
                    "MuJoCo has nq = {}, nv = {nv} for {} full coordinates",
                    m.nq,
                    model.n_full()
                ),
            });
        }
        let id = |kind: mj::mjtObj, name: &str| -> crate::Result<usize> {
            let c = CString::new(name).map_err(|_| Error::Mujoco {
                message: format!("name `{name}` contains NUL"),
            })?;
            // SAFETY: m is a valid model and c a valid C string.
            let i = unsafe { mj::mj_name2id(m, kind as i32, c.as_ptr()) };
            usize::try_from(i).map_err(|_| Error::Mujoco {
                message: format!("no MuJoCo object named `{name}`"),
            })
        };
        let mut adr = Vec::with_capacity(nv);
        for dof in &model.dofs {
            let j = id(mj::mjtObj::mjOBJ_JOINT, &dof.name)?;
            // SAFETY: j < njnt; jnt_qposadr has njnt entries.
            let a = unsafe { *m.jnt_qposadr.add(j) } as usize;
            let v = unsafe { *m.jnt_dofadr.add(j) } as usize;
            if a != v {
                return Err(Error::Mujoco {
                    message: format!("joint `{}` has qpos {a} but dof {v}", dof.name),
                });
            }
            adr.push(a);
        }
        let mut body_id = vec![0];
        for b in model.bodies.iter().skip(1) {
            body_id.push(id(mj::mjtObj::mjOBJ_BODY, &b.name)?);
        }
        let data = MjData::new(Box::new(mj_model));
        Ok(MujocoTwin {
            data,
            nv,
            adr,
            body_id,
            dense: vec![0.0; nv * nv],
            vec: vec![0.0; nv],
            jacp: vec![0.0; 3 * nv],
            jacr: vec![0.0; 3 * nv],
            notes: export.notes,
        })
    }

    fn ptrs(&mut self) -> (*const mj::mjModel, *mut mj::mjData) {
        let m: *const mj::mjModel = self.data.model().ffi();
        // SAFETY: the data belongs to this twin; MuJoCo functions receive valid pointers.
        let d: *mut mj::mjData = unsafe { self.data.ffi_mut() };
        (m, d)
    }

    /// Sets qpos = θ and qvel = θ̇ (musculo's full coordinates and rates).
    pub fn set_state(&mut self, theta: &[f64], theta_dot: &[f64]) {
        let (_, d) = self.ptrs();
        for (k, &a) in self.adr.iter().enumerate() {
            // SAFETY: a < nq = nv.
            unsafe {
                *(*d).qpos.add(a) = theta[k];
                *(*d).qvel.add(a) = theta_dot[k];
            }
        }
    }

    /// MuJoCo's mass matrix stages on the current state — mj_kinematics, mj_comPos, mj_crb,
    /// mj_fullM — leaving the dense matrix (MuJoCo's order) inside the twin.
    pub fn mass_matrix_stages(&mut self) {
        let (m, d) = self.ptrs();
        // SAFETY: valid model/data; dense has nv² entries.
        unsafe {
            mj::mj_kinematics(m, d);
            mj::mj_comPos(m, d);
            mj::mj_crb(m, d);
            mj::mj_fullM(m, d, self.dense.as_mut_ptr());
        }
    }

    /// MuJoCo's bias stages on the current state — mj_kinematics, mj_comPos, mj_comVel,
    /// mj_rne (without acceleration) — leaving C θ̇ + G (MuJoCo's order) inside the twin.
    pub fn bias_stages(&mut self) {
        let (m, d) = self.ptrs();
        // SAFETY: valid model/data; vec has nv entries.
        unsafe {
            mj::mj_kinematics(m, d);
            mj::mj_comPos(m, d);
            mj::mj_comVel(m, d);
            mj::mj_rne(m, d, 0, self.vec.as_mut_ptr());
        }
    }

    /// MuJoCo's inverse dynamics stages — mj_kinematics, mj_comPos, mj_comVel, mj_rne with
    /// acceleration — for qacc = θ̈, leaving M θ̈ + C θ̇ + G (MuJoCo's order) inside the twin.
    pub fn inverse_dynamics_stages(&mut self, theta_ddot: &[f64]) {
        let (m, d) = self.ptrs();
        // SAFETY: valid model/data; qacc has nv entries; vec has nv entries.
        unsafe {
            for (k, &a) in self.adr.iter().enumerate() {
                *(*d).qacc.add(a) = theta_ddot[k];
            }
            mj::mj_kinematics(m, d);
            mj::mj_comPos(m, d);
            mj::mj_comVel(m, d);
            mj::mj_rne(m, d, 1, self.vec.as_mut_ptr());
        }
    }

    /// τ_full = M_full θ̈ + C θ̇ + G in musculo's full-coordinate order.
    pub fn inverse_dynamics(
        &mut self,
        theta: &[f64],
        theta_dot: &[f64],
        theta_ddot: &[f64],
        out: &mut [f64],
    ) {
        self.set_state(theta, theta_dot);
        self.inverse_dynamics_stages(theta_ddot);
        for (i, &a) in self.adr.iter().enumerate() {
            out[i] = self.vec[a];
        }
    }

    /// Index of the MuJoCo tendon exported for the named path (muscle or path actuator).
    pub fn tendon_index(&self, name: &str) -> Option<usize> {
        let c = CString::new(name).ok()?;
        // SAFETY: valid model and C string.
        let i = unsafe {
            mj::mj_name2id(
                self.data.model().ffi(),
                mj::mjtObj::mjOBJ_TENDON as i32,
                c.as_ptr(),
            )
        };
        usize::try_from(i).ok()
    }

    /// Tendon lengths and ∂length/∂θ (MuJoCo's ten_length and ten_J after mj_kinematics,
    /// mj_comPos, mj_tendon) at qpos = θ: `lengths[k]`, `jacobian[(k, d)]` in musculo's
    /// full-coordinate order, for every MuJoCo tendon k.
    pub fn tendons(&mut self, theta: &[f64], lengths: &mut [f64], jacobian: &mut DMatrix<f64>) {
        let zeros = vec![0.0; theta.len()];
        self.set_state(theta, &zeros);
        let (m, d) = self.ptrs();
        // SAFETY: valid model/data; ten_J is stored sparse with the model's row structure.
        unsafe {
            mj::mj_kinematics(m, d);
            mj::mj_comPos(m, d);
            mj::mj_tendon(m, d);
            let nt = (*m).ntendon as usize;
            let mut dof_of = vec![usize::MAX; self.nv];
            for (k, &a) in self.adr.iter().enumerate() {
                dof_of[a] = k;
            }
            jacobian.fill(0.0);
            for t in 0..nt.min(lengths.len()) {
                lengths[t] = *(*d).ten_length.add(t);
                let adr = *(*m).ten_J_rowadr.add(t) as usize;
                for i in 0..*(*m).ten_J_rownnz.add(t) as usize {
                    let col = *(*m).ten_J_colind.add(adr + i) as usize;
                    jacobian[(t, dof_of[col])] = *(*d).ten_J.add(adr + i);
                }
            }
        }
    }

    /// Number of MuJoCo tendons.
    pub fn tendon_count(&self) -> usize {
        self.data.model().ffi().ntendon as usize
    }

    /// M_full(θ) in musculo's full-coordinate order.
    pub fn mass_matrix(&mut self, theta: &[f64], out: &mut DMatrix<f64>) {
        let zeros = vec![0.0; theta.len()];
        self.set_state(theta, &zeros);
        self.mass_matrix_stages();
        let nv = self.nv;
        for (i, &ai) in self.adr.iter().enumerate() {
            for (j, &aj) in self.adr.iter().enumerate() {
                out[(i, j)] = self.dense[ai * nv + aj];
            }
        }
    }

    /// bias_full(θ, θ̇) = C θ̇ + G in musculo's full-coordinate order.
    pub fn bias(&mut self, theta: &[f64], theta_dot: &[f64], out: &mut [f64]) {
        self.set_state(theta, theta_dot);
        self.bias_stages();
        for (i, &a) in self.adr.iter().enumerate() {
            out[i] = self.vec[a];
        }
    }

    /// Pose of a musculo body (rotation, origin) after the last stages run.
    pub fn body_pose(&mut self, body: usize) -> (Mat3, Vec3) {
        let (_, d) = self.ptrs();
        let b = self.body_id[body];
        // SAFETY: b < nbody; xmat is row-major 3×3 per body, xpos 3 per body.
        unsafe {
            let x = std::slice::from_raw_parts((*d).xmat.add(9 * b), 9);
            let p = std::slice::from_raw_parts((*d).xpos.add(3 * b), 3);
            (Mat3::from_row_slice(x), Vec3::new(p[0], p[1], p[2]))
        }
    }

    /// Full-coordinate Jacobian (6 × n_full; rows angular then linear velocity of the body
    /// origin, ground axes) of a musculo body, after the mass-matrix or bias stages.
    pub fn body_jacobian(&mut self, body: usize, out: &mut DMatrix<f64>) {
        let (m, d) = self.ptrs();
        let b = self.body_id[body] as i32;
        // SAFETY: jacp/jacr have 3·nv entries.
        unsafe { mj::mj_jacBody(m, d, self.jacp.as_mut_ptr(), self.jacr.as_mut_ptr(), b) };
        let nv = self.nv;
        for (k, &a) in self.adr.iter().enumerate() {
            for r in 0..3 {
                out[(r, k)] = self.jacr[r * nv + a];
                out[(3 + r, k)] = self.jacp[r * nv + a];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_different_library_version_is_a_readable_error() {
        let e = check_version(3_016_002, 3_017_000).unwrap_err().to_string();
        assert!(
            e.contains("3.16.2") && e.contains("3.17.0") && e.contains("setup-mujoco.sh"),
            "{e}"
        );
        assert!(check_version(EXPECTED_VERSION, EXPECTED_VERSION).is_ok());
        assert_eq!(
            linked_version(),
            EXPECTED_VERSION,
            "this build links {}",
            version_string(linked_version())
        );
    }
}
