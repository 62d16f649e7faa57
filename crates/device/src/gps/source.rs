//! (being written)
/// Placeholder.
pub struct GpsHandle;
/// Placeholder.
pub struct GpsSource;
/// Placeholder.
pub enum SourceConfig {}
/// Placeholder.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceState {}
