//! Integration tests: sim_tactor (being written).
