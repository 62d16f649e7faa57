//! A reader of raster PMTiles v3 archives (<https://github.com/protomaps/PMTiles/blob/main/spec/v3/spec.md>),
//! written for hostile files: every offset and length is checked against the file, directories are
//! bounded, and only raster tile types (PNG, JPEG, WebP) stored uncompressed are served.
//!
//! Layout: a 127-byte header, a root directory, optional JSON metadata, leaf directories and tile data.
//! A directory is a list of entries `(tile_id, offset, length, run_length)`; `run_length == 0` points at a
//! leaf directory. Tile ids number tiles along a Hilbert curve, zoom by zoom ([`zxy_to_tile_id`]).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::{MAX_TILE_BYTES, TileError, TileKey};

/// Length of the v3 header [bytes].
pub const HEADER_LEN: usize = 127;
/// Largest directory accepted, compressed or not [bytes].
const MAX_DIR_BYTES: u64 = 16 << 20;
/// Most entries accepted in one directory.
const MAX_DIR_ENTRIES: u64 = 1 << 20;
/// Directory levels followed at most (root + leaves; real archives use 2).
const MAX_DEPTH: usize = 4;

/// Internal (directory) compression codes of the spec.
const COMPRESSION_NONE: u8 = 1;
const COMPRESSION_GZIP: u8 = 2;

/// The header fields the reader uses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    /// Root directory offset and length.
    pub root: (u64, u64),
    /// Metadata offset and length.
    pub metadata: (u64, u64),
    /// Leaf directories section offset and length.
    pub leaves: (u64, u64),
    /// Tile data section offset and length.
    pub data: (u64, u64),
    /// Compression of directories and metadata (1 none, 2 gzip).
    pub internal_compression: u8,
    /// Compression of tiles (1 none).
    pub tile_compression: u8,
    /// Tile type (2 PNG, 3 JPEG, 4 WebP).
    pub tile_type: u8,
    /// Lowest zoom in the archive.
    pub min_zoom: u8,
    /// Highest zoom in the archive.
    pub max_zoom: u8,
}

/// One directory entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Entry {
    /// First tile id of the run.
    pub tile_id: u64,
    /// Offset in the tile data (or leaf directory) section.
    pub offset: u64,
    /// Length of the tile (or leaf directory).
    pub length: u32,
    /// Consecutive tile ids sharing this content; 0 = a leaf directory.
    pub run_length: u32,
}

/// The Hilbert tile id of `key`: the number of tiles of all lower zooms, `(4^z − 1)/3`, plus the position
/// of (x, y) along the Hilbert curve of order z (PMTiles v3 spec, "Tile IDs").
pub fn zxy_to_tile_id(key: TileKey) -> u64 {
    let z = u32::from(key.z);
    let mut acc: u64 = ((1u64 << (2 * z)) - 1) / 3;
    let (mut x, mut y) = (u64::from(key.x), u64::from(key.y));
    let mut s: u64 = if z == 0 { 0 } else { 1u64 << (z - 1) };
    while s > 0 {
        let rx = u64::from(x & s > 0);
        let ry = u64::from(y & s > 0);
        acc += s * s * ((3 * rx) ^ ry);
        if ry == 0 {
            if rx == 1 {
                x = s - 1 - (x & (s - 1));
                y = s - 1 - (y & (s - 1));
            }
            std::mem::swap(&mut x, &mut y);
        }
        x &= s.wrapping_sub(1);
        y &= s.wrapping_sub(1);
        s >>= 1;
    }
    acc
}

/// Reads a LEB128 varint at `*pos`, at most 10 bytes.
fn varint(buf: &[u8], pos: &mut usize) -> Option<u64> {
    let mut v: u64 = 0;
    for shift in (0..70).step_by(7) {
        let b = *buf.get(*pos)?;
        *pos += 1;
        v |= u64::from(b & 0x7f).checked_shl(shift)?;
        if b & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// Appends `v` as a LEB128 varint (used by the tests' writer).
pub fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    loop {
        let b = (v & 0x7f) as u8;
        v >>= 7;
        if v == 0 {
            out.push(b);
            return;
        }
        out.push(b | 0x80);
    }
}

/// Decodes an uncompressed directory.
pub fn parse_directory(buf: &[u8]) -> Option<Vec<Entry>> {
    let mut pos = 0;
    let n = varint(buf, &mut pos)?;
    // Every entry takes at least 4 bytes: a count beyond that is a lie.
    if n > MAX_DIR_ENTRIES || n > buf.len() as u64 {
        return None;
    }
    let n = n as usize;
    let mut entries = vec![Entry { tile_id: 0, offset: 0, length: 0, run_length: 0 }; n];
    let mut last = 0u64;
    for e in &mut entries {
        last = last.checked_add(varint(buf, &mut pos)?)?;
        e.tile_id = last;
    }
    for e in &mut entries {
        e.run_length = u32::try_from(varint(buf, &mut pos)?).ok()?;
    }
    for e in &mut entries {
        e.length = u32::try_from(varint(buf, &mut pos)?).ok()?;
    }
    for i in 0..n {
        let v = varint(buf, &mut pos)?;
        let offset = if v == 0 && i > 0 {
            let p = entries[i - 1];
            p.offset.checked_add(u64::from(p.length))?
        } else {
            v.checked_sub(1)?
        };
        entries[i].offset = offset;
    }
    Some(entries)
}

/// Encodes a directory (the tests' writer; the inverse of [`parse_directory`], no compression).
pub fn write_directory(entries: &[Entry]) -> Vec<u8> {
    let mut out = Vec::new();
    put_varint(&mut out, entries.len() as u64);
    let mut last = 0;
    for e in entries {
        put_varint(&mut out, e.tile_id - last);
        last = e.tile_id;
    }
    for e in entries {
        put_varint(&mut out, u64::from(e.run_length));
    }
    for e in entries {
        put_varint(&mut out, u64::from(e.length));
    }
    for e in entries {
        put_varint(&mut out, e.offset + 1);
    }
    out
}

/// Parses the 127-byte header.
pub fn parse_header(b: &[u8]) -> Result<Header, String> {
    if b.len() < HEADER_LEN || !b.starts_with(b"PMTiles") {
        return Err("not a PMTiles file (no \"PMTiles\" magic)".into());
    }
    if b[7] != 3 {
        return Err(format!("PMTiles version {} (only version 3 is read)", b[7]));
    }
    let u = |i: usize| {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[8 + 8 * i..16 + 8 * i]);
        u64::from_le_bytes(a)
    };
    Ok(Header {
        root: (u(0), u(1)),
        metadata: (u(2), u(3)),
        leaves: (u(4), u(5)),
        data: (u(6), u(7)),
        internal_compression: b[97],
        tile_compression: b[98],
        tile_type: b[99],
        min_zoom: b[100],
        max_zoom: b[101],
    })
}

/// Writes a header (the tests' writer): sections as given, the counts left 0 (unknown), bounds the world.
pub fn write_header(h: &Header) -> Vec<u8> {
    let mut b = Vec::with_capacity(HEADER_LEN);
    b.extend_from_slice(b"PMTiles");
    b.push(3);
    for v in
        [h.root.0, h.root.1, h.metadata.0, h.metadata.1, h.leaves.0, h.leaves.1, h.data.0, h.data.1, 0, 0, 0]
    {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&[
        1,
        h.internal_compression,
        h.tile_compression,
        h.tile_type,
        h.min_zoom,
        h.max_zoom,
    ]);
    for v in [-1_800_000_000i32, -850_000_000, 1_800_000_000, 850_000_000] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.push(h.min_zoom);
    b.extend_from_slice(&0i32.to_le_bytes());
    b.extend_from_slice(&0i32.to_le_bytes());
    b
}

/// An open PMTiles archive.
pub struct PmTilesReader {
    file: File,
    path: PathBuf,
    file_len: u64,
    /// The header.
    pub header: Header,
    root: Vec<Entry>,
    /// The last leaf directory read (tiles near each other share one).
    leaf: Option<((u64, u64), Vec<Entry>)>,
}

impl PmTilesReader {
    /// Opens `path` (a regular file only) and reads its header and root directory. Refuses vector archives
    /// and compressed tiles.
    pub fn open(path: &Path) -> Result<Self, TileError> {
        let what = path.display().to_string();
        let corrupt = |why: String| TileError::Corrupt { what: what.clone(), why };
        let io = |source| TileError::Io { what: what.clone(), source };
        // Regular files only: a FIFO or device given as the archive is refused, never opened.
        let mut file =
            vestnav_files::open_regular(path).map_err(|e| TileError::from_open(what.clone(), e))?;
        let file_len = file.metadata().map_err(io)?.len();
        let mut head = [0u8; HEADER_LEN];
        file.read_exact(&mut head).map_err(|_| corrupt("shorter than a PMTiles header".into()))?;
        let header = parse_header(&head).map_err(&corrupt)?;
        match header.tile_type {
            2..=4 => {}
            1 => return Err(corrupt(format!("vector (MVT) tiles: {}", crate::VECTOR_TILES_REFUSED))),
            t => return Err(corrupt(format!("tile type {t} is not PNG, JPEG or WebP"))),
        }
        if header.tile_compression > COMPRESSION_NONE {
            return Err(corrupt(format!(
                "tiles compressed with code {}: raster tiles must be stored as-is",
                header.tile_compression
            )));
        }
        if header.internal_compression != COMPRESSION_NONE && header.internal_compression != COMPRESSION_GZIP
        {
            return Err(corrupt(format!(
                "directory compression code {} is not supported (none or gzip)",
                header.internal_compression
            )));
        }
        let mut r = Self { file, path: path.to_owned(), file_len, header, root: Vec::new(), leaf: None };
        let (o, l) = r.header.root;
        r.root = r.read_directory(o, l)?;
        Ok(r)
    }

    /// The archive's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn corrupt(&self, why: impl Into<String>) -> TileError {
        TileError::Corrupt { what: self.path.display().to_string(), why: why.into() }
    }

    /// Reads `len` bytes at `offset`, after checking the range lies inside the file.
    fn read_at(&mut self, offset: u64, len: u64, cap: u64) -> Result<Vec<u8>, TileError> {
        let end = offset.checked_add(len).ok_or_else(|| self.corrupt("offset overflows"))?;
        if end > self.file_len {
            return Err(self.corrupt(format!(
                "range {offset}+{len} lies past the end of the file ({} bytes)",
                self.file_len
            )));
        }
        if len > cap {
            return Err(self.corrupt(format!("section of {len} bytes is over the {cap}-byte limit")));
        }
        let mut buf = vec![0u8; len as usize];
        let what = self.path.display().to_string();
        self.file
            .seek(SeekFrom::Start(offset))
            .and_then(|_| self.file.read_exact(&mut buf))
            .map_err(|source| TileError::Io { what, source })?;
        Ok(buf)
    }

    fn read_directory(&mut self, offset: u64, len: u64) -> Result<Vec<Entry>, TileError> {
        let raw = self.read_at(offset, len, MAX_DIR_BYTES)?;
        let bytes = if self.header.internal_compression == COMPRESSION_GZIP {
            let mut out = Vec::new();
            flate2::read::GzDecoder::new(&raw[..])
                .take(MAX_DIR_BYTES + 1)
                .read_to_end(&mut out)
                .map_err(|e| self.corrupt(format!("directory at {offset} does not decompress: {e}")))?;
            if out.len() as u64 > MAX_DIR_BYTES {
                return Err(self.corrupt("directory decompresses past the size limit"));
            }
            out
        } else {
            raw
        };
        parse_directory(&bytes).ok_or_else(|| self.corrupt(format!("directory at {offset} is malformed")))
    }

    /// The tile's bytes, `None` when the archive does not hold it.
    pub fn tile(&mut self, key: TileKey) -> Result<Option<Vec<u8>>, TileError> {
        if key.z < self.header.min_zoom || key.z > self.header.max_zoom {
            return Ok(None);
        }
        let id = zxy_to_tile_id(key);
        let mut dir: Option<Vec<Entry>> = None;
        for _ in 0..MAX_DEPTH {
            let entries = dir.as_deref().unwrap_or(&self.root);
            let Some(e) = find(entries, id) else { return Ok(None) };
            if e.run_length > 0 {
                if u64::from(e.length) > MAX_TILE_BYTES as u64 {
                    return Err(TileError::TooLarge {
                        what: super::tile_what(key, &self.path.display().to_string()),
                        bytes: u64::from(e.length),
                    });
                }
                let at = self
                    .header
                    .data
                    .0
                    .checked_add(e.offset)
                    .ok_or_else(|| self.corrupt("tile offset overflows"))?;
                return self.read_at(at, u64::from(e.length), MAX_TILE_BYTES as u64).map(Some);
            }
            let at = self
                .header
                .leaves
                .0
                .checked_add(e.offset)
                .ok_or_else(|| self.corrupt("leaf offset overflows"))?;
            let span = (at, u64::from(e.length));
            let entries = match self.leaf.take() {
                Some((s, d)) if s == span => d,
                _ => self.read_directory(span.0, span.1)?,
            };
            self.leaf = Some((span, entries.clone()));
            dir = Some(entries);
        }
        Err(self.corrupt("leaf directories nest deeper than 4 levels"))
    }
}

/// The entry holding tile `id`: the last entry with `tile_id <= id`, if it is a leaf pointer or its run
/// covers `id`.
fn find(entries: &[Entry], id: u64) -> Option<Entry> {
    let i = entries.partition_point(|e| e.tile_id <= id).checked_sub(1)?;
    let e = *entries.get(i)?;
    (e.run_length == 0 || id - e.tile_id < u64::from(e.run_length)).then_some(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k(z: u8, x: u32, y: u32) -> TileKey {
        TileKey::new(z, x, y).unwrap()
    }

    #[test]
    fn hilbert_ids_of_the_spec() {
        // From the PMTiles reference implementation's tests.
        assert_eq!(zxy_to_tile_id(k(0, 0, 0)), 0);
        assert_eq!(zxy_to_tile_id(k(1, 0, 0)), 1);
        assert_eq!(zxy_to_tile_id(k(1, 0, 1)), 2);
        assert_eq!(zxy_to_tile_id(k(1, 1, 1)), 3);
        assert_eq!(zxy_to_tile_id(k(1, 1, 0)), 4);
        assert_eq!(zxy_to_tile_id(k(2, 0, 0)), 5);
        assert_eq!(zxy_to_tile_id(k(12, 3423, 1763)), 19_078_479);
        // Every tile of a zoom gets its own id within the zoom's block.
        let mut ids: Vec<u64> =
            (0..8).flat_map(|x| (0..8).map(move |y| zxy_to_tile_id(k(3, x, y)))).collect();
        ids.sort_unstable();
        assert_eq!(ids, (21..85).collect::<Vec<_>>());
    }

    #[test]
    fn directory_round_trip_and_garbage() {
        let entries = vec![
            Entry { tile_id: 1, offset: 0, length: 10, run_length: 1 },
            Entry { tile_id: 2, offset: 10, length: 5, run_length: 2 },
            Entry { tile_id: 9, offset: 100, length: 7, run_length: 0 },
        ];
        assert_eq!(parse_directory(&write_directory(&entries)).unwrap(), entries);
        assert_eq!(find(&entries, 3).unwrap().offset, 10);
        assert!(find(&entries, 4).is_none());
        assert!(find(&entries, 0).is_none());
        assert_eq!(find(&entries, 50).unwrap().run_length, 0);
        for junk in [
            &[][..],
            &[0xff; 11],
            &[5, 1],
            &[0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x01],
        ] {
            assert!(parse_directory(junk).is_none());
        }
        let h = Header {
            root: (127, 3),
            metadata: (130, 0),
            leaves: (130, 0),
            data: (130, 9),
            internal_compression: 1,
            tile_compression: 1,
            tile_type: 2,
            min_zoom: 0,
            max_zoom: 3,
        };
        let b = write_header(&h);
        assert_eq!(b.len(), HEADER_LEN);
        assert_eq!(parse_header(&b).unwrap(), h);
        assert!(parse_header(&b[..50]).is_err());
    }
}
