//! Integration tests: nav (being written).
