//! The egui side of the map's tiles: [`SourceTiles`], the one `walkers::Tiles` implementation (textures
//! from the decoded tiles the `vestnav_tiles` loader threads hand over), and [`MapTiles`], the map's
//! tile switch, indicator and Tiles window. Everything without egui — sources, the cache, PMTiles and
//! MBTiles, the tile folder, the HTTP fetch, the prefetch, checks and decoding — is the `vestnav_tiles`
//! crate.

pub mod extract;
pub mod local;
pub mod ui;

pub use extract::MapExtract;
pub use local::SourceTiles;
pub use ui::MapTiles;
