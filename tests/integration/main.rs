//! Integration tests of the vestnav binary.
