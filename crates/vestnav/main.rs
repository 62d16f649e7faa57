//! vestnav: the console (no subcommand) and headless subcommands.
fn main() {}
