//! First-order activation dynamics, forward and inverse. (In progress.)
