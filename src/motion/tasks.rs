//! What inverse kinematics fits: model markers following target columns of a motion, and
//! coordinates held near values (OpenSim's IKMarkerTask and IKCoordinateTask). The motion
//! readers' skeleton maps produce these tasks and [`crate::solve::ik`] solves them, so they
//! sit here, below both.

/// A model marker that follows a target column of the motion.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerTask {
    /// Index in `Model::markers`.
    pub marker: usize,
    /// Column of the target motion.
    pub target: usize,
    pub weight: f64,
}

/// An independent coordinate held near a value (OpenSim's IKCoordinateTask).
#[derive(Clone, Debug, PartialEq)]
pub struct CoordinateTask {
    /// Index in q.
    pub q: usize,
    pub weight: f64,
    /// The value per frame, or one value for every frame.
    pub value: Vec<f64>,
}

/// What the solver fits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IkTasks {
    pub markers: Vec<MarkerTask>,
    pub coordinates: Vec<CoordinateTask>,
}
