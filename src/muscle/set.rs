//! The batch API: every muscle of a model per frame — musculotendon lengths and speeds, the
//! n × m moment-arm matrix, and Hill-type forces — into a preallocated workspace.

use super::hill::{HillMuscle, MuscleState};
use super::path::{PathData, PathSet, compute_paths, compute_paths_parallel};
use crate::dynamics::Data;
use crate::error::Error;
use crate::model::Model;

/// The muscles of a model: their paths and force models, in `Model::forces` order.
#[derive(Clone, Debug)]
pub struct MuscleSet {
    pub paths: PathSet,
    pub muscles: Vec<HillMuscle>,
}

impl MuscleSet {
    /// Builds every muscle of `model`. A muscle of a class musculo does not model, or with
    /// invalid parameters, is an error naming it.
    pub fn new(model: &Model) -> crate::Result<MuscleSet> {
        let paths = PathSet::muscles(model)?;
        let muscles = paths
            .paths
            .iter()
            .map(|p| {
                let f = &model.forces[p.force];
                HillMuscle::from_force_element(f).map_err(|message| Error::Model {
                    // A muscle of a force-set file is reported in that file.
                    file: f.file_or(&model.source).to_string(),
                    line: f.line,
                    element: format!("{} \"{}\"", f.kind, f.name),
                    message,
                })
            })
            .collect::<crate::Result<Vec<_>>>()?;
        Ok(MuscleSet { paths, muscles })
    }

    pub fn len(&self) -> usize {
        self.muscles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.muscles.is_empty()
    }

    /// Muscle names, in order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.muscles.iter().map(|m| m.name())
    }
}

/// Which tendon model the forces use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TendonMode {
    /// Each muscle's own: rigid if its file sets `ignore_tendon_compliance`, otherwise the
    /// compliant-tendon equilibrium (fiber and tendon forces balanced for ℓ, ℓ̇).
    #[default]
    AsModel,
    /// Rigid tendon for every muscle: the closed form F = (a f_L f_V + f_PE) F_max cos α, as
    /// static optimization with muscle physiology uses it.
    Rigid,
}

/// Workspace of a [`MuscleSet`]: one per thread.
#[derive(Clone, Debug)]
pub struct MuscleData {
    /// ℓ_MT, ℓ̇_MT and the moment arms r (n × m, r = −∂ℓ/∂q).
    pub paths: PathData,
    /// The state of each muscle (fiber length, velocity, forces…) from the last
    /// [`compute_muscles`].
    pub state: Vec<MuscleState>,
    /// Tendon force of each muscle (N).
    pub force: Vec<f64>,
}

impl MuscleData {
    pub fn new(model: &Model, set: &MuscleSet) -> MuscleData {
        let probe = set
            .muscles
            .first()
            .map(|m| m.state_rigid_tendon(0.0, 0.0, 0.0));
        MuscleData {
            paths: PathData::new(model, &set.paths),
            state: probe.map(|p| vec![p; set.len()]).unwrap_or_default(),
            force: vec![0.0; set.len()],
        }
    }
}

/// One frame for all muscles at the state of `data` (velocity stage for speeds): lengths,
/// speeds and moment arms, then each muscle's force at its activation with the tendon model
/// `tendon`. With `parallel`, the paths are computed on rayon's threads (worth it only for
/// many muscles with expensive wrapping; for a frame of a gait model the serial call is
/// faster). The generalized muscle forces are `moment_arms · force`.
pub fn compute_muscles(
    model: &Model,
    data: &Data,
    set: &MuscleSet,
    activation: &[f64],
    tendon: TendonMode,
    parallel: bool,
    out: &mut MuscleData,
) -> crate::Result<()> {
    if activation.len() != set.len() {
        return Err(Error::invalid(
            "activation",
            format!("expected {} values, got {}", set.len(), activation.len()),
        ));
    }
    if let Some(i) = activation.iter().position(|a| !a.is_finite()) {
        return Err(Error::invalid(
            "activation",
            format!("value {i} is not finite"),
        ));
    }
    if parallel {
        compute_paths_parallel(model, data, &set.paths, &mut out.paths)?;
    } else {
        compute_paths(model, data, &set.paths, &mut out.paths)?;
    }
    for (k, m) in set.muscles.iter().enumerate() {
        let (a, l, v) = (activation[k], out.paths.length[k], out.paths.speed[k]);
        let s = match tendon {
            TendonMode::AsModel => m.state(a, l, v),
            TendonMode::Rigid => m.state_rigid_tendon(a, l, v),
        };
        out.state[k] = s;
        out.force[k] = s.tendon_force;
    }
    Ok(())
}
