//! Frames: `postcard(header, message)` followed by its CRC-32 (little endian), COBS-encoded
//! and ended by a zero byte; a streaming reader that cuts a byte stream into frames. What
//! the header and message mean is `msg`'s and the link's business.

use super::{MAX_FRAME, MAX_PAYLOAD};
use crate::job::CRC;
use serde::{Deserialize, Serialize};

/// Why a frame could not be made or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WireError {
    /// The message does not fit `MAX_PAYLOAD` (or the output buffer).
    TooLarge,
    /// The bytes between two delimiters are not valid COBS.
    Cobs,
    /// Shorter than a CRC.
    Short,
    /// The CRC does not match: corrupted on the way.
    Crc,
    /// The CRC matches but the message does not decode (another protocol version?).
    Decode,
    /// Bytes left over after the message.
    Trailing,
}

impl core::fmt::Display for WireError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            WireError::TooLarge => "message too large for a frame",
            WireError::Cobs => "frame is not valid COBS",
            WireError::Short => "frame too short",
            WireError::Crc => "frame CRC mismatch (corrupted)",
            WireError::Decode => "frame does not decode (protocol mismatch?)",
            WireError::Trailing => "frame has bytes after its message",
        })
    }
}

/// Encodes `header` and `msg` into `out` as one frame including the final zero byte;
/// returns the frame's length. `out` needs `MAX_FRAME + 1` bytes for any message.
pub fn encode<H: Serialize, M: Serialize>(
    header: &H,
    msg: &M,
    out: &mut [u8],
) -> Result<usize, WireError> {
    let mut raw = [0u8; MAX_PAYLOAD + 4];
    let n = postcard::to_slice(&(header, msg), &mut raw[..MAX_PAYLOAD])
        .map_err(|_| WireError::TooLarge)?
        .len();
    let crc = CRC.checksum(&raw[..n]);
    raw[n..n + 4].copy_from_slice(&crc.to_le_bytes());
    let len = cobs::try_encode(&raw[..n + 4], out).map_err(|_| WireError::TooLarge)?;
    if len >= out.len() {
        return Err(WireError::TooLarge);
    }
    out[len] = 0;
    Ok(len + 1)
}

/// Decodes one frame (without its delimiter) in place: checks COBS, CRC and that the
/// message uses every byte. Borrowed fields (chunk data) point into `frame`.
pub fn decode<'a, H: Deserialize<'a>, M: Deserialize<'a>>(
    frame: &'a mut [u8],
) -> Result<(H, M), WireError> {
    parse(open(frame)?)
}

/// Undoes COBS in place and checks the CRC; returns the payload (header and message).
pub fn open(frame: &mut [u8]) -> Result<&[u8], WireError> {
    let n = cobs::decode_in_place(frame).map_err(|_| WireError::Cobs)?;
    if n < 4 {
        return Err(WireError::Short);
    }
    let body = &frame[..n - 4];
    let crc = u32::from_le_bytes([frame[n - 4], frame[n - 3], frame[n - 2], frame[n - 1]]);
    if CRC.checksum(body) != crc {
        return Err(WireError::Crc);
    }
    Ok(body)
}

/// Decodes a payload `open` returned; every byte must belong to the message.
pub fn parse<'a, H: Deserialize<'a>, M: Deserialize<'a>>(
    payload: &'a [u8],
) -> Result<(H, M), WireError> {
    let (hm, rest) = postcard::take_from_bytes::<(H, M)>(payload).map_err(|_| WireError::Decode)?;
    if !rest.is_empty() {
        return Err(WireError::Trailing);
    }
    Ok(hm)
}

/// Reads only the parts every protocol version shares: the header, and the version if the
/// message is a hello (variant 0, version first). Lets either side name both versions when
/// the rest of a hello from another version does not decode.
pub fn peek_hello<'a, H: Deserialize<'a>>(payload: &'a [u8]) -> Option<(H, u16)> {
    let (h, rest) = postcard::take_from_bytes::<H>(payload).ok()?;
    let (tag, rest) = postcard::take_from_bytes::<u32>(rest).ok()?;
    let (version, _) = postcard::take_from_bytes::<u16>(rest).ok()?;
    (tag == 0).then_some((h, version))
}

/// True if sequence number `a` comes after `b` (wrapping, within half the number space).
pub fn seq_after(a: u16, b: u16) -> bool {
    let d = a.wrapping_sub(b);
    d != 0 && d < 0x8000
}

/// Cuts a byte stream into frames. Holds at most `MAX_FRAME` bytes; a longer run without
/// a delimiter is dropped up to the next delimiter and reported once.
pub struct FrameReader {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflow: bool,
    ready: bool,
}

/// What `FrameReader::feed` found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// A frame of this many bytes is in `frame()` until the next `feed`.
    Frame(usize),
    /// A frame longer than `MAX_FRAME` was dropped.
    Oversize,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameReader {
    /// An empty reader.
    pub const fn new() -> Self {
        FrameReader {
            buf: [0; MAX_FRAME],
            len: 0,
            overflow: false,
            ready: false,
        }
    }

    /// Takes bytes up to and including the first delimiter in `bytes`. Returns how many it
    /// took and what completed, if anything; call again with the rest.
    pub fn feed(&mut self, bytes: &[u8]) -> (usize, Option<Event>) {
        if self.ready {
            self.ready = false;
            self.len = 0;
        }
        for (i, &b) in bytes.iter().enumerate() {
            if b == 0 {
                let len = self.len;
                let overflow = self.overflow;
                self.overflow = false;
                if overflow {
                    self.len = 0;
                    return (i + 1, Some(Event::Oversize));
                }
                if len == 0 {
                    // Empty frames (two delimiters) resynchronise; nothing to report.
                    continue;
                }
                self.ready = true;
                return (i + 1, Some(Event::Frame(len)));
            }
            if self.len < MAX_FRAME {
                self.buf[self.len] = b;
                self.len += 1;
            } else {
                self.overflow = true;
            }
        }
        (bytes.len(), None)
    }

    /// The frame `feed` last reported, for `decode` to work on in place.
    pub fn frame(&mut self, len: usize) -> &mut [u8] {
        &mut self.buf[..len.min(MAX_FRAME)]
    }

    /// Forgets a partial frame (after a reconnect).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
        self.ready = false;
    }
}
