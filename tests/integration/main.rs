//! Integration tests of the vestnav binary and of the crates working together, one module per topic.

mod gps;
mod nav;
mod sim_tactor;
mod sim_wave;
mod wtcu;
