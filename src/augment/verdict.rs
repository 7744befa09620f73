//! A verdict per clip — `ok`, `suspect` or `failed` — from its quality figures
//! ([`ClipQuality`]), with the one reason that decided it.
//!
//! - `failed`: the tensors cannot be used — a figure is not finite, IK could not follow the
//!   clip (worst error above [`IK_ERROR_FAILED`]), or the contacts carry less than
//!   [`CONTACT_CONSISTENCY_FAILED`] of the clip's vertical support demand (most of the
//!   loading sits on the residual actuators, so the contact forces and the joint moments that
//!   balance them are invented);
//! - `suspect`: a figure beyond the limits OpenSim's best-practice checklist recommends
//!   (below); the clip is written and usable, but should be looked at;
//! - `ok`: within all of them.
//!
//! The limits of `suspect` are the upper ends of the ranges in the OpenSim documentation's
//! evaluation checklist, "Simulation with OpenSim – Best Practices" (the OpenSim team's
//! pages "Modeling and Simulation Best Practices", which accompany Hicks, Uchida, Seth,
//! Rajagopal & Delp 2015, "Is my model good enough? Best practices for verification and
//! validation of musculoskeletal models and simulations of movement", J Biomech Eng
//! 137:020905): IK maximum marker error below 4 cm and RMS below about 2 cm; peak residual
//! forces 10–25 N and RMS 5–15 N; peak residual moments below 75 N·m and RMS below 50 N·m;
//! peak reserve torques below 10 % of the corresponding peak joint torques. The checklist
//! states the residual limits in newtons for adult subjects; the figures are kept relative to
//! body weight (BW = m·g) and body weight × 1 m, and compared in newtons (figure × the clip's
//! m·g).
//!
//! Where several limits are crossed, the reason names the one crossed by the largest factor
//! (value ÷ limit) among those of the verdict's severity; all crossed limits are listed in
//! [`ClipVerdict::crossed`]. Without muscles (`musculo evaluate`, [`super::chain::ChainOptions::muscles`]
//! false) the reserve limit does not apply.

/// Quality figures of one clip (the manifest's per-clip entry).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct ClipQuality {
    pub frames: usize,
    pub rate_hz: f64,
    /// Median over frames of the per-frame marker/joint RMSE of IK (m).
    pub ik_rmse_median: f64,
    /// Largest single marker/joint error of IK (m).
    pub ik_error_max: f64,
    /// Frames with a coordinate at its bound after IK.
    pub ik_frames_at_bound: usize,
    /// The model markers (or joint-centre markers) IK fitted, in the column order of the array
    /// `ik_marker_error`.
    #[serde(default)]
    pub ik_markers: Vec<String>,
    /// Per IK marker (in the order of [`ClipQuality::ik_markers`]): the RMS over the frames
    /// with a target of its error ‖model marker − target‖ (m); none for a marker with no
    /// target in any frame (`null` in the manifest).
    #[serde(default)]
    pub ik_rmse_by_marker: Vec<Option<f64>>,
    /// Share of the frames (of [`ClipQuality::frames`]) that ended IK with a coordinate at its
    /// bound.
    #[serde(default)]
    pub ik_frames_at_bound_share: f64,
    /// Peak residual force: the largest |τ| over the floating base's translational rows and
    /// the frames (what no contact explained, carried by the residual actuators), relative
    /// to body weight m·g.
    pub residual_force_max_bw: f64,
    /// RMS residual force: the largest over the translational floating-base rows of the RMS
    /// over frames of that row's τ, relative to body weight (as OpenSim reports the RMS of
    /// each residual actuator).
    #[serde(default)]
    pub residual_force_rms_bw: f64,
    /// Largest residual moment (N·m) about the pelvis coordinates.
    pub residual_moment_max: f64,
    /// [`ClipQuality::residual_moment_max`] relative to body weight × 1 m (m·g · 1 m).
    #[serde(default)]
    pub residual_moment_max_bwm: f64,
    /// RMS residual moment: the largest over the rotational floating-base rows of the RMS
    /// over frames, relative to body weight × 1 m.
    #[serde(default)]
    pub residual_moment_rms_bwm: f64,
    /// Σ|reserve moments| / Σ|joint moments| over the joint coordinates and frames.
    pub reserve_share: f64,
    /// The largest, over the joint coordinates, of the coordinate's peak |reserve| over its
    /// peak |joint moment| (OpenSim's "peak reserve torque / peak joint torque"); 0 without
    /// muscles. Coordinates whose peak joint moment stays below the reserve's optimal force
    /// ([`ChainOptions::reserve_optimal_force`](super::chain::ChainOptions::reserve_optimal_force), 1 N·m) are left out: there the reserve's
    /// control stays below 1, where static optimization's cost x² prices it like a muscle's
    /// activation, and a share of a few hundredths of a N·m (the default model's forearm
    /// rotation: 0.04 of 0.008 N·m) says nothing about the muscles' strength.
    #[serde(default)]
    pub reserve_peak_share: f64,
    /// The coordinate of [`ClipQuality::reserve_peak_share`].
    #[serde(default)]
    pub reserve_peak_coordinate: String,
    /// The coordinates whose reserves carry most, with their share of the same total
    /// (Σ|reserve_c| / Σ|joint moments|), largest first (at most 5).
    pub reserve_by_coordinate: Vec<(String, f64)>,
    /// Frames static optimization could not solve exactly.
    pub so_unsolved_frames: usize,
    /// Muscle samples of the clip: frames × muscles (0 without muscles); the "of how many"
    /// of [`ClipQuality::clamped_excitations`] and
    /// [`ClipQuality::muscle_samples_at_full_activation`].
    #[serde(default)]
    pub muscle_samples: usize,
    /// Muscle samples whose activation static optimization left on its upper bound (1): the
    /// muscle gives all it has, and any more is carried by the coordinate's reserve. The QP
    /// projects its iterates onto the bounds, so a saturated activation sits on the bound to
    /// round-off (counted within 10⁻⁹ of it).
    #[serde(default)]
    pub muscle_samples_at_full_activation: usize,
    /// [`ClipQuality::muscle_samples_at_full_activation`] / [`ClipQuality::muscle_samples`]
    /// (0 without muscles).
    #[serde(default)]
    pub full_activation_share: f64,
    /// Excitation samples that inverse activation dynamics had to clamp to the excitation
    /// range by more than [`CLAMP_REPORTED`](super::chain::CLAMP_REPORTED): where static optimization's activations change
    /// faster than activation dynamics allow.
    pub clamped_excitations: usize,
    /// Fraction of frames with at least one contact.
    pub contact_fraction: f64,
    /// Share of the clip's vertical support demand that the contact forces carry:
    /// Σ_t min(G_t⁺, D_t⁺) / Σ_t D_t⁺, with D_t = up·(Σ_i m_i (a_i − g)) the vertical
    /// external force the body's motion needs at frame t (the force the root joint transmits
    /// in inverse dynamics) and G_t the vertical component of all contact forces at t
    /// (estimated, or measured with `--external-loads`/`--force-plates`); x⁺ = max(x, 0).
    /// 1: the contacts carry all the support; what they miss is carried by the residual
    /// actuators. None when the clip needs no support (no gravity, or all in flight).
    #[serde(default)]
    pub contact_consistency: Option<f64>,
    /// Body mass (kg) and height scale of the model used.
    pub body_mass: f64,
    /// Whether the contact estimate took the floor as a treadmill (given, or detected from
    /// the stance feet), and the belt's velocity in ground (m/s; zeros for a floor at rest or
    /// measured loads).
    #[serde(default)]
    pub treadmill: bool,
    #[serde(default)]
    pub belt_velocity: [f64; 3],
    /// Body weight m·g (N) of the model used: the unit of the residual figures.
    #[serde(default)]
    pub body_weight: f64,
    /// The verdict on the clip ([`super::verdict`]); None in records written before verdicts
    /// existed.
    #[serde(default)]
    pub verdict: Option<ClipVerdict>,
}

/// IK's worst single error (m) above which a clip's warnings say that IK could not follow
/// it: a fitting map leaves tens of millimetres (HumanML3D's sample 176 mm at most, with its
/// arms overhead beyond the model's ranges); metres mean a wrong map, axes or unit.
pub const IK_ERROR_WARNED: f64 = 0.3;

/// IK's worst single marker (or joint-centre) error above which a clip is `failed` (m): the
/// chain's own warning threshold ([`IK_ERROR_WARNED`]) — metres of error mean a
/// wrong skeleton map, axes or length unit, and every tensor follows a pose the input does
/// not show.
pub const IK_ERROR_FAILED: f64 = IK_ERROR_WARNED;

/// Share of the clip's vertical support demand the contacts must carry
/// ([`ClipQuality::contact_consistency`]) below which a clip is `failed`: under half, most of
/// the body's support is carried by the residual actuators on the pelvis (a clip hanging from
/// bars the model cannot hold, feet never detected on the floor, measured loads that miss
/// most steps), so the contact forces — and the joint moments that balance them — describe
/// another motion than the recorded one.
pub const CONTACT_CONSISTENCY_FAILED: f64 = 0.5;

/// IK's worst marker error above which a clip is `suspect` (m): OpenSim's checklist, "Is the
/// maximum marker error less than 4 cm?".
pub const IK_ERROR_SUSPECT: f64 = 0.04;

/// Median over frames of IK's per-frame RMS marker error above which a clip is `suspect`
/// (m): OpenSim's checklist, "Is the RMS error less than ~2 cm?".
pub const IK_RMSE_SUSPECT: f64 = 0.02;

/// Peak residual force above which a clip is `suspect` (N): OpenSim's checklist, "Are the
/// peak residual forces less than 10–25 N?" (the upper end).
pub const RESIDUAL_FORCE_PEAK_SUSPECT: f64 = 25.0;

/// RMS residual force above which a clip is `suspect` (N): OpenSim's checklist, "Are the RMS
/// residual forces less than 5–15 N?" (the upper end).
pub const RESIDUAL_FORCE_RMS_SUSPECT: f64 = 15.0;

/// Peak residual moment above which a clip is `suspect` (N·m): OpenSim's checklist, "Are the
/// peak residual moments less than 75 Nm?".
pub const RESIDUAL_MOMENT_PEAK_SUSPECT: f64 = 75.0;

/// RMS residual moment above which a clip is `suspect` (N·m): OpenSim's checklist, "Are the
/// RMS residual moments less than 50 Nm?".
pub const RESIDUAL_MOMENT_RMS_SUSPECT: f64 = 50.0;

/// Peak reserve torque, as a share of the same coordinate's peak joint torque, above which a
/// clip is `suspect`: OpenSim's checklist, "Are the peak reserve actuator torques less than
/// 10 % of the corresponding peak joint torques?".
pub const RESERVE_PEAK_SHARE_SUSPECT: f64 = 0.10;

/// The verdict on a clip, from best to worst.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Ok,
    Suspect,
    Failed,
}

impl Verdict {
    /// The verdict's name as the manifest and the command line spell it.
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Ok => "ok",
            Verdict::Suspect => "suspect",
            Verdict::Failed => "failed",
        }
    }
}

/// A clip's verdict and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClipVerdict {
    pub verdict: Verdict,
    /// The limit that decided it (the crossed limit of the verdict's severity with the
    /// largest value ÷ limit): the figure, its value and the limit; None for `ok`.
    pub reason: Option<String>,
    /// Every crossed limit, in the same words, worst first within each severity.
    pub crossed: Vec<String>,
}

impl ClipVerdict {
    /// The verdict of a clip the chain could not compute: `failed`, for the error `reason`.
    pub fn not_computed(reason: &str) -> ClipVerdict {
        ClipVerdict {
            verdict: Verdict::Failed,
            reason: Some(format!("not computed: {reason}")),
            crossed: Vec::new(),
        }
    }
}

/// One crossed limit: its severity, value ÷ limit and wording.
struct Crossing {
    verdict: Verdict,
    factor: f64,
    text: String,
}

/// The verdict on a clip from its quality figures (see the module documentation for the
/// rules and their sources).
pub fn judge(q: &ClipQuality) -> ClipVerdict {
    let mut crossed = Vec::new();
    let weight = q.body_weight;
    // --- failed ---
    let figures = [
        ("IK RMSE median", q.ik_rmse_median),
        ("IK worst error", q.ik_error_max),
        ("residual force peak", q.residual_force_max_bw),
        ("residual force RMS", q.residual_force_rms_bw),
        ("residual moment peak", q.residual_moment_max_bwm),
        ("residual moment RMS", q.residual_moment_rms_bwm),
        ("reserve share", q.reserve_share),
        ("peak reserve share", q.reserve_peak_share),
        ("contact consistency", q.contact_consistency.unwrap_or(0.0)),
    ];
    for (name, value) in figures {
        if !value.is_finite() {
            crossed.push(Crossing {
                verdict: Verdict::Failed,
                factor: f64::INFINITY,
                text: format!("{name} is {value}: not a finite figure"),
            });
        }
    }
    if q.ik_error_max > IK_ERROR_FAILED {
        crossed.push(Crossing {
            verdict: Verdict::Failed,
            factor: q.ik_error_max / IK_ERROR_FAILED,
            text: format!(
                "IK worst error {:.0} mm > {:.0} mm: IK could not follow the clip (check the \
                 skeleton map, its axes and the length unit)",
                q.ik_error_max * 1e3,
                IK_ERROR_FAILED * 1e3
            ),
        });
    }
    if let Some(c) = q.contact_consistency
        && c < CONTACT_CONSISTENCY_FAILED
    {
        crossed.push(Crossing {
            verdict: Verdict::Failed,
            // how many times short of the limit
            factor: CONTACT_CONSISTENCY_FAILED / c.max(1e-12),
            text: format!(
                "contact consistency {:.2} < {CONTACT_CONSISTENCY_FAILED}: the contacts carry \
                 {:.0} % of the clip's vertical support demand, the residual actuators the rest",
                c,
                100.0 * c
            ),
        });
    }
    // --- suspect (OpenSim's best-practice checklist) ---
    let mut limit = |value: f64, limit: f64, text: String| {
        if value > limit {
            crossed.push(Crossing {
                verdict: Verdict::Suspect,
                factor: value / limit,
                text,
            });
        }
    };
    limit(
        q.ik_error_max,
        IK_ERROR_SUSPECT,
        format!(
            "IK worst error {:.0} mm > {:.0} mm",
            q.ik_error_max * 1e3,
            IK_ERROR_SUSPECT * 1e3
        ),
    );
    limit(
        q.ik_rmse_median,
        IK_RMSE_SUSPECT,
        format!(
            "IK RMSE median {:.1} mm > {:.0} mm",
            q.ik_rmse_median * 1e3,
            IK_RMSE_SUSPECT * 1e3
        ),
    );
    // residual figures, relative to body weight (and 1 m), compared in N and N·m
    for (value_bw, unit, limit_n, what) in [
        (
            q.residual_force_max_bw,
            "BW",
            RESIDUAL_FORCE_PEAK_SUSPECT,
            "residual force peak",
        ),
        (
            q.residual_force_rms_bw,
            "BW",
            RESIDUAL_FORCE_RMS_SUSPECT,
            "residual force RMS",
        ),
        (
            q.residual_moment_max_bwm,
            "BW·m",
            RESIDUAL_MOMENT_PEAK_SUSPECT,
            "residual moment peak",
        ),
        (
            q.residual_moment_rms_bwm,
            "BW·m",
            RESIDUAL_MOMENT_RMS_SUSPECT,
            "residual moment RMS",
        ),
    ] {
        if weight > 0.0 {
            let newtons = value_bw * weight;
            let n = if unit == "BW" { "N" } else { "N·m" };
            limit(
                newtons,
                limit_n,
                format!(
                    "{what} {value_bw:.3} {unit} ({newtons:.0} {n}) > {limit_n:.0} {n} \
                     ({:.3} {unit})",
                    limit_n / weight
                ),
            );
        }
    }
    if q.muscle_samples > 0 {
        limit(
            q.reserve_peak_share,
            RESERVE_PEAK_SHARE_SUSPECT,
            format!(
                "peak reserve torque {:.0} % of the peak joint torque of {} > {:.0} %",
                100.0 * q.reserve_peak_share,
                q.reserve_peak_coordinate,
                100.0 * RESERVE_PEAK_SHARE_SUSPECT
            ),
        );
    }
    // worst first: severity, then factor; equal factors keep the order above
    crossed.sort_by(|a, b| {
        b.verdict
            .cmp(&a.verdict)
            .then_with(|| b.factor.total_cmp(&a.factor))
    });
    let verdict = crossed.first().map_or(Verdict::Ok, |c| c.verdict);
    ClipVerdict {
        verdict,
        reason: crossed.first().map(|c| c.text.clone()),
        crossed: crossed.into_iter().map(|c| c.text).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clip of a 75 kg body well inside every limit.
    fn good() -> ClipQuality {
        let weight = 75.0 * 9.80665;
        ClipQuality {
            frames: 100,
            rate_hz: 100.0,
            ik_rmse_median: 0.005,
            ik_error_max: 0.02,
            residual_force_max_bw: 10.0 / weight,
            residual_force_rms_bw: 5.0 / weight,
            residual_moment_max: 30.0,
            residual_moment_max_bwm: 30.0 / weight,
            residual_moment_rms_bwm: 20.0 / weight,
            reserve_share: 0.01,
            reserve_peak_share: 0.05,
            reserve_peak_coordinate: "hip_flexion_r".into(),
            muscle_samples: 100 * 80,
            contact_consistency: Some(0.98),
            body_mass: 75.0,
            body_weight: weight,
            ..ClipQuality::default()
        }
    }

    /// The verdict of `good()` changed by `change`.
    fn verdict_of(change: impl Fn(&mut ClipQuality)) -> ClipVerdict {
        let mut q = good();
        change(&mut q);
        judge(&q)
    }

    #[test]
    fn a_clip_within_every_limit_is_ok() {
        let v = judge(&good());
        assert_eq!(v.verdict, Verdict::Ok, "{v:?}");
        assert_eq!(v.reason, None);
        assert!(v.crossed.is_empty());
    }

    #[test]
    fn each_limit_of_opensims_checklist_makes_a_clip_suspect_just_beyond_it() {
        // (the checklist's figures, written out: a change of a constant must show here)
        let w = 75.0 * 9.80665;
        type Change = Box<dyn Fn(&mut ClipQuality, f64)>;
        let cases: Vec<(&str, f64, Change)> = vec![
            ("IK worst error", 0.040, Box::new(|q, v| q.ik_error_max = v)),
            (
                "IK RMSE median",
                0.020,
                Box::new(|q, v| q.ik_rmse_median = v),
            ),
            (
                "residual force peak",
                25.0,
                Box::new(move |q, v| q.residual_force_max_bw = v / w),
            ),
            (
                "residual force RMS",
                15.0,
                Box::new(move |q, v| q.residual_force_rms_bw = v / w),
            ),
            (
                "residual moment peak",
                75.0,
                Box::new(move |q, v| q.residual_moment_max_bwm = v / w),
            ),
            (
                "residual moment RMS",
                50.0,
                Box::new(move |q, v| q.residual_moment_rms_bwm = v / w),
            ),
            (
                "peak reserve torque",
                0.10,
                Box::new(|q, v| q.reserve_peak_share = v),
            ),
        ];
        for (figure, limit, change) in cases {
            let below = verdict_of(|q| change(q, limit * 0.99));
            assert_eq!(below.verdict, Verdict::Ok, "{figure} below: {below:?}");
            let above = verdict_of(|q| change(q, limit * 1.01));
            assert_eq!(above.verdict, Verdict::Suspect, "{figure} above: {above:?}");
            let reason = above.reason.unwrap();
            assert!(reason.starts_with(figure), "{figure}: {reason}");
            assert_eq!(above.crossed.len(), 1, "{:?}", above.crossed);
        }
    }

    #[test]
    fn a_fit_ik_cannot_follow_or_contacts_that_carry_under_half_fail_the_clip() {
        let v = verdict_of(|q| q.ik_error_max = 0.31);
        assert_eq!(v.verdict, Verdict::Failed, "{v:?}");
        assert!(
            v.reason
                .as_ref()
                .unwrap()
                .contains("IK worst error 310 mm > 300 mm")
        );
        // the same error is also beyond the suspect limit: listed after the failure
        assert_eq!(v.crossed.len(), 2, "{:?}", v.crossed);
        assert_eq!(
            verdict_of(|q| q.ik_error_max = 0.29).verdict,
            Verdict::Suspect
        );
        let v = verdict_of(|q| q.contact_consistency = Some(0.49));
        assert_eq!(v.verdict, Verdict::Failed, "{v:?}");
        assert!(
            v.reason
                .unwrap()
                .starts_with("contact consistency 0.49 < 0.5")
        );
        assert_eq!(
            verdict_of(|q| q.contact_consistency = Some(0.51)).verdict,
            Verdict::Ok
        );
        // a clip that needs no support is not judged on its contacts
        assert_eq!(
            verdict_of(|q| q.contact_consistency = None).verdict,
            Verdict::Ok
        );
        let v = verdict_of(|q| q.residual_force_rms_bw = f64::NAN);
        assert_eq!(v.verdict, Verdict::Failed, "{v:?}");
        assert!(v.reason.unwrap().contains("not a finite figure"));
    }

    #[test]
    fn the_reason_is_the_limit_crossed_by_the_largest_factor() {
        let w = 75.0 * 9.80665;
        let v = verdict_of(|q| {
            q.ik_error_max = 0.05; // 1.25 × its limit
            q.residual_force_max_bw = 100.0 / w; // 4 ×
            q.reserve_peak_share = 0.2; // 2 ×
        });
        assert_eq!(v.verdict, Verdict::Suspect);
        assert!(
            v.reason
                .as_ref()
                .unwrap()
                .starts_with("residual force peak"),
            "{v:?}"
        );
        assert!(v.crossed[1].starts_with("peak reserve torque"), "{v:?}");
        assert!(v.crossed[2].starts_with("IK worst error"), "{v:?}");
        // a failure decides over any suspect figure, however large
        let v = verdict_of(|q| {
            q.residual_force_max_bw = 10.0;
            q.contact_consistency = Some(0.4);
        });
        assert_eq!(v.verdict, Verdict::Failed);
        assert!(v.reason.unwrap().starts_with("contact consistency"));
    }

    #[test]
    fn without_muscles_the_reserve_limit_does_not_apply() {
        let v = verdict_of(|q| {
            q.muscle_samples = 0;
            q.reserve_peak_share = 0.5;
        });
        assert_eq!(v.verdict, Verdict::Ok, "{v:?}");
    }

    #[test]
    fn a_record_written_before_verdicts_still_loads_without_one() {
        // the quality figures as records held them before the verdict's figures existed
        let old = r#"{"frames":10,"rate_hz":100.0,"ik_rmse_median":0.01,"ik_error_max":0.02,
            "ik_frames_at_bound":0,"residual_force_max_bw":0.1,"residual_moment_max":5.0,
            "reserve_share":0.01,"reserve_by_coordinate":[],"so_unsolved_frames":0,
            "clamped_excitations":3,"contact_fraction":1.0,"body_mass":75.0}"#;
        let q: ClipQuality = serde_json::from_str(old).unwrap();
        assert_eq!(q.verdict, None);
        assert_eq!(q.contact_consistency, None);
        assert_eq!((q.muscle_samples, q.body_weight), (0, 0.0));
        assert_eq!(q.clamped_excitations, 3);
    }

    #[test]
    fn verdicts_order_from_ok_to_failed_and_spell_as_the_manifest() {
        assert!(Verdict::Ok < Verdict::Suspect && Verdict::Suspect < Verdict::Failed);
        assert_eq!(
            serde_json::to_string(&Verdict::Suspect).unwrap(),
            "\"suspect\""
        );
        assert_eq!(Verdict::Failed.name(), "failed");
    }
}
