//! Wrapping of a straight path segment over a wrap surface (sphere, cylinder, ellipsoid,
//! torus), as OpenSim defines it. (In progress.)
