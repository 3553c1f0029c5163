//! A PNG that is only a header: it says `w` x `h` grey pixels and holds no pixel data, so
//! a refusal that names a size limit can only have come from reading the header, and a
//! decoder that went further would fail with another message. Shared by the limit tests.

use std::path::Path;

/// Writes the header-only PNG (grey, `bit_depth` bits per pixel) to `path`.
pub fn write(path: &Path, w: u32, h: u32, bit_depth: u8) {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut c = kind.to_vec();
        c.extend_from_slice(data);
        png.extend_from_slice(&c);
        png.extend_from_slice(&crc32(&c).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[bit_depth, 0, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    // A zlib header and nothing more: the header is readable, the pixels are not there.
    chunk(b"IDAT", &[0x78, 0x9c]);
    chunk(b"IEND", &[]);
    std::fs::write(path, png).unwrap();
}

/// PNG's chunk CRC (CRC-32, reflected, polynomial 0xEDB88320).
fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}
