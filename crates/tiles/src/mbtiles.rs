//! Writing an MBTiles file (<https://github.com/mapbox/mbtiles-spec/blob/master/1.3/spec.md>): the
//! prefetch's other target. The schema is the standard one — `metadata(name, value)` with `name`, `format`,
//! `bounds`, `minzoom`, `maxzoom`, `attribution`, `type`, `version`; `tiles(zoom_level, tile_column,
//! tile_row, tile_data)` with TMS rows ([`TileKey::tms_row`]: `tile_row = 2^z − 1 − y`) and the unique index
//! `tile_index` on `(zoom_level, tile_column, tile_row)` — so the file opens in the console
//! ([`super::store::MbTilesStore`]) and in other MBTiles readers.
//!
//! Tiles are written in batches, each batch one SQLite transaction (rollback journal): a run killed at
//! any instant leaves a valid file holding whole tiles only, and the next run skips the tiles present
//! ([`MbTilesWriter::present`]).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use super::{BBox, TileError, TileFormat, TileKey, sniff};

/// What the `metadata` table says about the file.
#[derive(Debug, Clone, PartialEq)]
pub struct MbTilesMeta {
    /// The tileset's name.
    pub name: String,
    /// The area; on a resumed file the union with what was there.
    pub bbox: BBox,
    /// Lowest zoom (a resumed file keeps the lower of the two).
    pub min_zoom: u8,
    /// Highest zoom (a resumed file keeps the higher of the two).
    pub max_zoom: u8,
    /// Attribution the provider requires.
    pub attribution: String,
}

/// An MBTiles file open for writing.
pub struct MbTilesWriter {
    conn: rusqlite::Connection,
    path: PathBuf,
}

const SCHEMA: &str = "
    CREATE TABLE IF NOT EXISTS metadata (name TEXT, value TEXT);
    CREATE UNIQUE INDEX IF NOT EXISTS name ON metadata (name);
    CREATE TABLE IF NOT EXISTS tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);
    CREATE UNIQUE INDEX IF NOT EXISTS tile_index ON tiles (zoom_level, tile_column, tile_row);";

impl MbTilesWriter {
    /// Creates `path`, or opens it to resume (a regular file only): checks it (`PRAGMA quick_check`), creates the schema where
    /// missing and writes the metadata (zoom range and bounds widened to cover what the file held).
    pub fn open(path: &Path, meta: &MbTilesMeta) -> Result<Self, TileError> {
        let what = path.display().to_string();
        let sql = |e: rusqlite::Error| TileError::Corrupt {
            what: what.clone(),
            why: format!("cannot write it as an MBTiles file: {e}"),
        };
        // A FIFO or device given as the file is refused before SQLite could open (and block on) it.
        super::refuse_non_regular(path)?;
        let conn = rusqlite::Connection::open(path).map_err(sql)?;
        conn.busy_timeout(std::time::Duration::from_secs(5)).map_err(sql)?;
        let check: String = conn.query_row("PRAGMA quick_check", [], |r| r.get(0)).map_err(sql)?;
        if check != "ok" {
            return Err(TileError::Corrupt { what, why: format!("the SQLite file is damaged: {check}") });
        }
        conn.execute_batch(SCHEMA).map_err(sql)?;
        let old = |name: &str| -> Option<String> {
            conn.query_row("SELECT value FROM metadata WHERE name = ?1", [name], |r| r.get::<_, String>(0))
                .ok()
        };
        let zoom = |name: &str| old(name).and_then(|v| v.trim().parse::<u8>().ok());
        let min_zoom = zoom("minzoom").map_or(meta.min_zoom, |z| z.min(meta.min_zoom));
        let max_zoom = zoom("maxzoom").map_or(meta.max_zoom, |z| z.max(meta.max_zoom));
        let mut b = meta.bbox;
        if let Some(v) = old("bounds") {
            let n: Vec<f64> = v.split(',').filter_map(|s| s.trim().parse().ok()).collect();
            if let [w, s, e, nn] = n[..] {
                b = BBox {
                    min_lat: b.min_lat.min(s),
                    min_lon: b.min_lon.min(w),
                    max_lat: b.max_lat.max(nn),
                    max_lon: b.max_lon.max(e),
                };
            }
        }
        let rows = [
            ("name", meta.name.clone()),
            ("type", "baselayer".to_owned()),
            ("version", "1.0".to_owned()),
            ("description", "made by vestnav's prefetch".to_owned()),
            ("bounds", format!("{:.6},{:.6},{:.6},{:.6}", b.min_lon, b.min_lat, b.max_lon, b.max_lat)),
            ("minzoom", min_zoom.to_string()),
            ("maxzoom", max_zoom.to_string()),
            ("attribution", meta.attribution.clone()),
        ];
        {
            let tx = conn.unchecked_transaction().map_err(sql)?;
            for (k, v) in rows {
                tx.execute("INSERT OR REPLACE INTO metadata (name, value) VALUES (?1, ?2)", [k, &v])
                    .map_err(sql)?;
            }
            tx.commit().map_err(sql)?;
        }
        Ok(Self { conn, path: path.to_owned() })
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Which of `keys` the file already holds.
    pub fn present(&self, keys: &[TileKey]) -> Result<HashSet<TileKey>, TileError> {
        let mut stmt = self
            .conn
            .prepare("SELECT 1 FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3")
            .map_err(|e| self.corrupt(&e))?;
        let mut out = HashSet::new();
        for &k in keys {
            if stmt.exists(rusqlite::params![k.z, k.x, k.tms_row()]).map_err(|e| self.corrupt(&e))? {
                out.insert(k);
            }
        }
        Ok(out)
    }

    /// Writes `tiles` in one transaction (all of them or, when killed, none); the first tile's format
    /// (sniffed) becomes the `format` metadata when none is recorded.
    pub fn write_batch(&mut self, tiles: &[(TileKey, Vec<u8>)]) -> Result<(), TileError> {
        let tx = self
            .conn
            .transaction()
            .map_err(|e| TileError::Corrupt { what: self.path.display().to_string(), why: e.to_string() })?;
        let res = (|| -> rusqlite::Result<()> {
            if let Some((_, first)) = tiles.first() {
                let format = match sniff(first) {
                    Some(TileFormat::Jpeg) => "jpg",
                    Some(TileFormat::Webp) => "webp",
                    _ => "png",
                };
                tx.execute("INSERT OR IGNORE INTO metadata (name, value) VALUES ('format', ?1)", [format])?;
            }
            let mut stmt = tx.prepare(
                "INSERT OR REPLACE INTO tiles (zoom_level, tile_column, tile_row, tile_data) VALUES (?1, ?2, ?3, ?4)",
            )?;
            for (k, b) in tiles {
                stmt.execute(rusqlite::params![k.z, k.x, k.tms_row(), b])?;
            }
            drop(stmt);
            tx.commit()
        })();
        res.map_err(|e| self.corrupt(&e))
    }

    fn corrupt(&self, e: &rusqlite::Error) -> TileError {
        TileError::Corrupt { what: self.path.display().to_string(), why: e.to_string() }
    }
}

#[cfg(test)]
mod tests {
    use super::super::store::{MbTilesStore, TileStore as _};
    use super::*;

    /// A real 2x2 PNG (the reader checks the header's declared size).
    fn png() -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        image::RgbImage::new(2, 2).write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    }

    #[test]
    fn written_tiles_read_back_through_the_reader() {
        let dir = std::env::temp_dir().join(format!("vestnav-mbwrite-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.mbtiles");
        let meta = MbTilesMeta {
            name: "test".into(),
            bbox: BBox { min_lat: 42.35, min_lon: -71.11, max_lat: 42.36, max_lon: -71.09 },
            min_zoom: 3,
            max_zoom: 4,
            attribution: "© test".into(),
        };
        let a = TileKey::new(3, 5, 1).unwrap();
        let b = TileKey::new(4, 2, 9).unwrap();
        let mut w = MbTilesWriter::open(&path, &meta).unwrap();
        let png = png();
        let mut pa = png.clone();
        pa.push(1);
        w.write_batch(&[(a, pa.clone()), (b, png.clone())]).unwrap();
        assert_eq!(w.present(&[a, b, TileKey::new(4, 0, 0).unwrap()]).unwrap(), HashSet::from([a, b]));
        drop(w);
        // Resumed with a wider zoom range: the metadata widens, the tiles stay.
        let w =
            MbTilesWriter::open(&path, &MbTilesMeta { min_zoom: 5, max_zoom: 6, ..meta.clone() }).unwrap();
        assert_eq!(w.present(&[a]).unwrap().len(), 1);
        drop(w);
        let mut r = MbTilesStore::open(&path).unwrap();
        let info = r.info();
        assert_eq!((info.min_zoom, info.max_zoom), (3, 6));
        assert_eq!(info.attribution.as_deref(), Some("© test"));
        assert_eq!(r.get(a).unwrap().unwrap().bytes, pa);
        assert_eq!(r.get(b).unwrap().unwrap().bytes, png);
        assert!(r.get(TileKey::new(3, 5, 6).unwrap()).unwrap().is_none(), "TMS row, not XYZ");
        // The rows are TMS rows, and the file is what the spec says.
        let c = rusqlite::Connection::open(&path).unwrap();
        let row: u32 = c
            .query_row("SELECT tile_row FROM tiles WHERE zoom_level = 3 AND tile_column = 5", [], |r| {
                r.get(0)
            })
            .unwrap();
        assert_eq!(row, 6);
        let get = |n: &str| -> String {
            c.query_row("SELECT value FROM metadata WHERE name = ?1", [n], |r| r.get(0)).unwrap()
        };
        assert_eq!(get("format"), "png");
        assert_eq!(get("bounds"), "-71.110000,42.350000,-71.090000,42.360000");
        let ok: String = c.query_row("PRAGMA integrity_check", [], |r| r.get(0)).unwrap();
        assert_eq!(ok, "ok");
        drop(c);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
