//! Checking and decoding one tile's bytes, which may come from anyone: the format is read from the
//! signature (never from a name or a content type), the size the image *declares* in its header is
//! checked before a single pixel is decoded, and decoding runs under the image crate's memory limits.
//!
//! Where each format keeps its size: PNG in the `IHDR` chunk that must follow the signature (PNG 1.2
//! spec §11.2.2: width and height, 4 bytes big-endian each); JPEG in the start-of-frame segment (ITU-T
//! T.81 §B.2.2: `SOFn`, length, precision, height and width, 2 bytes big-endian each), found by walking
//! the marker segments; WebP in its first chunk (RFC 9649): `VP8 ` (lossy: 14-bit width and height
//! after the key frame's start code), `VP8L` (lossless: width − 1 and height − 1 in 14 bits each after
//! the signature byte `0x2F`) or `VP8X` (extended: canvas width − 1 and height − 1 in 24 bits each).

use super::{MAX_TILE_BYTES, MAX_TILE_PX, TileError};

/// The image formats a tile may be in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TileFormat {
    /// PNG (`89 50 4E 47 0D 0A 1A 0A`).
    Png,
    /// JPEG (`FF D8 FF`).
    Jpeg,
    /// WebP (`RIFF....WEBP`).
    Webp,
}

impl TileFormat {
    /// The format's name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Png => "PNG",
            Self::Jpeg => "JPEG",
            Self::Webp => "WebP",
        }
    }
}

/// A decoded tile: `width × height` pixels, 4 bytes each (RGBA, not premultiplied), row by row from
/// the top.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TileImage {
    /// Width [px].
    pub width: u32,
    /// Height [px].
    pub height: u32,
    /// `width · height · 4` bytes.
    pub rgba: Vec<u8>,
}

/// The format by the file's signature (magic bytes), never by its name or a server's content type.
pub fn sniff(bytes: &[u8]) -> Option<TileFormat> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some(TileFormat::Png)
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some(TileFormat::Jpeg)
    } else if bytes.len() >= 12 && bytes.starts_with(b"RIFF") && bytes.get(8..12) == Some(b"WEBP") {
        Some(TileFormat::Webp)
    } else {
        None
    }
}

fn be16(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at + 2)?;
    Some(u32::from(s[0]) << 8 | u32::from(s[1]))
}

fn be32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_be_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn le_n(b: &[u8], at: usize, n: usize) -> Option<u32> {
    let s = b.get(at..at + n)?;
    Some(s.iter().rev().fold(0u32, |acc, &x| acc << 8 | u32::from(x)))
}

/// The width and height [px] the image's header declares, read without decoding anything; `Err` says
/// what is missing from the header.
pub fn declared_size(bytes: &[u8], format: TileFormat) -> Result<(u32, u32), &'static str> {
    match format {
        TileFormat::Png => {
            // Signature (8), then the IHDR chunk: length 13, type, width, height.
            if be32(bytes, 8) != Some(13) || bytes.get(12..16) != Some(b"IHDR") {
                return Err("PNG without an IHDR header after its signature");
            }
            Ok((
                be32(bytes, 16).ok_or("PNG header cut short")?,
                be32(bytes, 20).ok_or("PNG header cut short")?,
            ))
        }
        TileFormat::Jpeg => jpeg_size(bytes),
        TileFormat::Webp => {
            let short = "WebP header cut short";
            match bytes.get(12..16) {
                Some(b"VP8 ") => {
                    // Frame tag (3 bytes), start code 9D 01 2A, then 2-byte width and height whose top
                    // two bits are a scale, not part of the size.
                    if bytes.get(23..26) != Some(&[0x9D, 0x01, 0x2A]) {
                        return Err("WebP (lossy) without a key frame start code");
                    }
                    let w = le_n(bytes, 26, 2).ok_or(short)? & 0x3FFF;
                    let h = le_n(bytes, 28, 2).ok_or(short)? & 0x3FFF;
                    Ok((w, h))
                }
                Some(b"VP8L") => {
                    if bytes.get(20) != Some(&0x2F) {
                        return Err("WebP (lossless) without its signature byte");
                    }
                    let v = le_n(bytes, 21, 4).ok_or(short)?;
                    Ok(((v & 0x3FFF) + 1, ((v >> 14) & 0x3FFF) + 1))
                }
                Some(b"VP8X") => {
                    let w = le_n(bytes, 24, 3).ok_or(short)? + 1;
                    let h = le_n(bytes, 27, 3).ok_or(short)? + 1;
                    Ok((w, h))
                }
                _ => Err("WebP without a VP8, VP8L or VP8X chunk first"),
            }
        }
    }
}

/// Walks a JPEG's marker segments up to its start-of-frame segment and reads the frame's size.
fn jpeg_size(b: &[u8]) -> Result<(u32, u32), &'static str> {
    let mut i = 2; // after SOI
    loop {
        // A marker: one or more 0xFF fill bytes, then the code.
        if b.get(i) != Some(&0xFF) {
            return Err("JPEG segment without a marker before its frame header");
        }
        while b.get(i) == Some(&0xFF) {
            i += 1;
        }
        let Some(&code) = b.get(i) else { return Err("JPEG ends before its frame header") };
        i += 1;
        match code {
            // Stand-alone markers (TEM, RSTn): no length.
            0x01 | 0xD0..=0xD7 => continue,
            0xD9 | 0xDA => return Err("JPEG without a frame header before its scan"),
            _ => {}
        }
        let len = be16(b, i).ok_or("JPEG ends before its frame header")? as usize;
        if len < 2 {
            return Err("JPEG segment with a length under 2");
        }
        let is_sof = matches!(code, 0xC0..=0xCF) && !matches!(code, 0xC4 | 0xC8 | 0xCC);
        if is_sof {
            // Length (2), precision (1), height (2), width (2).
            let h = be16(b, i + 3).ok_or("JPEG frame header cut short")?;
            let w = be16(b, i + 5).ok_or("JPEG frame header cut short")?;
            return Ok((w, h));
        }
        i += len;
    }
}

/// Checks that `bytes` are an acceptable tile without decoding it: at most [`MAX_TILE_BYTES`], a PNG,
/// JPEG or WebP signature, and a header declaring at most [`MAX_TILE_PX`] pixels a side (and not 0).
pub fn check_tile_bytes(bytes: &[u8], what: &str) -> Result<TileFormat, TileError> {
    if bytes.len() > MAX_TILE_BYTES {
        return Err(TileError::TooLarge { what: what.to_owned(), bytes: bytes.len() as u64 });
    }
    let format = sniff(bytes).ok_or_else(|| TileError::NotAnImage { what: what.to_owned() })?;
    let (width, height) = declared_size(bytes, format)
        .map_err(|why| TileError::Decode { what: what.to_owned(), why: why.to_owned() })?;
    if width == 0 || height == 0 || width > MAX_TILE_PX || height > MAX_TILE_PX {
        return Err(TileError::Oversize { what: what.to_owned(), format: format.name(), width, height });
    }
    Ok(format)
}

/// Decodes a tile: checks it ([`check_tile_bytes`]), then decodes with the image crate's memory limits
/// (each side at most [`MAX_TILE_PX`], at most 16 MiB allocated) into RGBA.
pub fn decode_tile(bytes: &[u8], what: &str) -> Result<TileImage, TileError> {
    let format = match check_tile_bytes(bytes, what)? {
        TileFormat::Png => image::ImageFormat::Png,
        TileFormat::Jpeg => image::ImageFormat::Jpeg,
        TileFormat::Webp => image::ImageFormat::WebP,
    };
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TILE_PX);
    limits.max_image_height = Some(MAX_TILE_PX);
    limits.max_alloc = Some(16 << 20);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| TileError::Decode { what: what.to_owned(), why: e.to_string() })?;
    let rgba = img.to_rgba8();
    let (width, height) = rgba.dimensions();
    if width == 0 || height == 0 {
        return Err(TileError::Decode { what: what.to_owned(), why: "empty image".into() });
    }
    Ok(TileImage { width, height, rgba: rgba.into_raw() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(format: image::ImageFormat, w: u32, h: u32) -> Vec<u8> {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 7) as u8, (y * 3) as u8, 90]));
        let mut out = std::io::Cursor::new(Vec::new());
        match format {
            image::ImageFormat::WebP => {
                let rgba = image::DynamicImage::ImageRgb8(img).to_rgba8();
                rgba.write_to(&mut out, format).unwrap();
            }
            _ => img.write_to(&mut out, format).unwrap(),
        }
        out.into_inner()
    }

    /// What the image crate (an independent reader) says the header declares.
    fn reference(bytes: &[u8], format: image::ImageFormat) -> (u32, u32) {
        image::ImageReader::with_format(std::io::Cursor::new(bytes), format).into_dimensions().unwrap()
    }

    #[test]
    fn declared_sizes_agree_with_the_image_crate_for_encoded_images() {
        for (w, h) in [(1, 1), (256, 256), (512, 256), (3, 700), (1024, 1), (1025, 2)] {
            for (f, tf) in [
                (image::ImageFormat::Png, TileFormat::Png),
                (image::ImageFormat::Jpeg, TileFormat::Jpeg),
                (image::ImageFormat::WebP, TileFormat::Webp),
            ] {
                let b = encode(f, w, h);
                assert_eq!(sniff(&b), Some(tf));
                assert_eq!(declared_size(&b, tf), Ok(reference(&b, f)), "{f:?} {w}x{h}");
                assert_eq!(declared_size(&b, tf), Ok((w, h)));
                let ok = check_tile_bytes(&b, "t");
                if w <= MAX_TILE_PX && h <= MAX_TILE_PX {
                    assert_eq!(ok.unwrap(), tf);
                    let img = decode_tile(&b, "t").unwrap();
                    assert_eq!((img.width, img.height, img.rgba.len()), (w, h, (w * h * 4) as usize));
                } else {
                    let e = ok.unwrap_err().to_string();
                    assert!(e.contains(&format!("declares {w}x{h} px")), "{e}");
                }
            }
        }
    }

    /// Lossy (`VP8 `) and extended (`VP8X`) WebP headers written from RFC 9649's layout, read by us
    /// and by the image crate's WebP decoder.
    #[test]
    fn webp_lossy_and_extended_headers_agree_with_the_image_crate() {
        for (w, h) in [(256u32, 256u32), (16383, 1), (16383, 16383), (640, 77)] {
            let mut b = b"RIFF\0\0\0\0WEBPVP8 ".to_vec();
            b.extend_from_slice(&100u32.to_le_bytes());
            // Frame tag: key frame, version 0, shown, first partition size 1.
            b.extend_from_slice(&[0x10, 0x00, 0x00, 0x9D, 0x01, 0x2A]);
            b.extend_from_slice(&(w as u16).to_le_bytes());
            b.extend_from_slice(&(h as u16).to_le_bytes());
            b.resize(128, 0);
            let n = (b.len() - 8) as u32;
            b[4..8].copy_from_slice(&n.to_le_bytes());
            assert_eq!(declared_size(&b, TileFormat::Webp), Ok((w, h)));
            assert_eq!(declared_size(&b, TileFormat::Webp), Ok(reference(&b, image::ImageFormat::WebP)));
        }
        for (w, h) in [(256u32, 512u32), (20000, 20000)] {
            let mut b = b"RIFF\0\0\0\0WEBPVP8X".to_vec();
            b.extend_from_slice(&10u32.to_le_bytes());
            b.extend_from_slice(&[0, 0, 0, 0]);
            b.extend_from_slice(&(w - 1).to_le_bytes()[..3]);
            b.extend_from_slice(&(h - 1).to_le_bytes()[..3]);
            // The image chunk a VP8X file must carry (a 1x1 lossless header will do for the size).
            b.extend_from_slice(b"VP8L\x06\0\0\0\x2F\0\0\0\0\0");
            let n = (b.len() - 8) as u32;
            b[4..8].copy_from_slice(&n.to_le_bytes());
            assert_eq!(declared_size(&b, TileFormat::Webp), Ok((w, h)));
            assert_eq!(declared_size(&b, TileFormat::Webp), Ok(reference(&b, image::ImageFormat::WebP)));
        }
    }

    /// A PNG whose IHDR declares 20000x20000 (the header of a decompression bomb) is refused, naming
    /// the size, before anything is decoded.
    #[test]
    fn oversize_headers_are_refused_with_the_reason() {
        let mut png = encode(image::ImageFormat::Png, 4, 4);
        png[16..20].copy_from_slice(&20_000u32.to_be_bytes());
        png[20..24].copy_from_slice(&20_000u32.to_be_bytes());
        let e = check_tile_bytes(&png, "tile 3/1/2 of a.mbtiles").unwrap_err();
        assert!(e.is_refusal());
        assert_eq!(
            e.to_string(),
            format!(
                "tile 3/1/2 of a.mbtiles refused: PNG declares 20000x20000 px, more than {MAX_TILE_PX} px a side"
            )
        );
        let mut jpeg = encode(image::ImageFormat::Jpeg, 8, 8);
        let sof = jpeg.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
        jpeg[sof + 5..sof + 7].copy_from_slice(&5000u16.to_be_bytes());
        let e = decode_tile(&jpeg, "j").unwrap_err().to_string();
        assert!(e.contains("JPEG declares 8x5000 px"), "{e}");
        let mut zero = encode(image::ImageFormat::Png, 4, 4);
        zero[16..20].copy_from_slice(&0u32.to_be_bytes());
        assert!(check_tile_bytes(&zero, "z").unwrap_err().to_string().contains("declares 0x4 px"));
    }

    #[test]
    fn hostile_bytes_are_refused_without_panic() {
        assert!(matches!(decode_tile(b"<html>", "t"), Err(TileError::NotAnImage { .. })));
        let big = vec![0x89; MAX_TILE_BYTES + 1];
        assert!(matches!(decode_tile(&big, "t"), Err(TileError::TooLarge { .. })));
        // A PNG signature followed by garbage: an error naming the tile, no panic.
        let e = decode_tile(b"\x89PNG\r\n\x1a\ngarbage", "x/1/2/3.png").unwrap_err();
        assert!(e.to_string().contains("x/1/2/3.png"));
        assert_eq!(sniff(b"RIFF\0\0\0\0WEBPVP8 "), Some(TileFormat::Webp));
        assert_eq!(sniff(&[0xFF, 0xD8, 0xFF, 0xE0]), Some(TileFormat::Jpeg));
        // Every prefix of real images: never a panic, always a decision.
        for f in [image::ImageFormat::Png, image::ImageFormat::Jpeg, image::ImageFormat::WebP] {
            let b = encode(f, 16, 16);
            for n in 0..b.len().min(400) {
                let _ = check_tile_bytes(&b[..n], "p");
            }
        }
        // JPEG segment lengths that point past the end or loop.
        for j in [
            &[0xFF, 0xD8, 0xFF, 0xE0, 0xFF, 0xFF][..],
            &[0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x00],
            &[0xFF, 0xD8, 0xFF],
        ] {
            assert!(check_tile_bytes(j, "j").is_err());
        }
    }
}
