//! Integration tests: wtcu (being written).
