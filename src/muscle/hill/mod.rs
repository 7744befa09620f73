//! Hill-type muscle models: Thelen 2003, Millard 2012 equilibrium, De Groote 2016.
//! (In progress.)
