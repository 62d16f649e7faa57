//! Integration tests: sim_wave (being written).
