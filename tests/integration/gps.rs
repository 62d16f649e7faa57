//! Integration tests: gps (being written).
