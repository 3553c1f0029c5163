//! The USB link's wire format, shared by the firmware and the host tools: message types
//! (`msg`), and frames (`frame`): postcard bytes + CRC-32, COBS-encoded, ended by a zero
//! byte. The reliability rules (sessions, sequence numbers, cumulative acks, credits) are
//! described here and carried out by `device::link` on the board and by the host's client;
//! transports (USB CDC-ACM, serial ports, in-memory test links) live with their users.
//!
//! # The exchange
//! Strictly request and reply: the host sends `Request`s, each in a frame with a
//! `HostHeader { session, seq }`; the device answers every frame it accepts with one frame
//! whose `DeviceHeader { session, next, credit }` says which sequence number it expects
//! next (a cumulative ack) and how many more job chunks it can buffer beyond that.
//!
//! - `Hello` opens a session (any `seq`): the device expects `seq + 1` next. A hello
//!   with another `PROTOCOL_VERSION` is answered with the device's version and refused,
//!   so both sides can name both versions. The frame headers and the first field of both
//!   hello messages never change between versions.
//! - The device acts on a request only if its `seq` is the one expected: a duplicate of the
//!   last control request gets the same reply again (never a second action); older
//!   duplicates and frames from the future get a bare ack with the expected `next`, so the
//!   sender goes back to it (go-back-N). Frames that fail their CRC or do not decode are
//!   dropped unanswered.
//! - Job chunks may be pipelined: up to `credit` chunks past `next`. Control requests
//!   are sent one at a time, with no chunk in flight.
//! - A chunk carries its byte offset as well: after a reconnect the host asks (hello) how
//!   much of the job the device holds and continues from exactly there.

pub mod frame;
pub mod msg;

pub use frame::{decode, encode, open, parse, peek_hello, seq_after, FrameReader, WireError};
pub use msg::*;

/// Version of the link protocol; changes whenever the bytes of any message change.
/// 3: `Request::Park` and `Request::Refill`, and the config's `pause` section (the
/// `LoadConfig` bytes).
pub const PROTOCOL_VERSION: u16 = 3;
/// Largest job chunk, bytes: 16 USB full-speed packets; a multiple of the flash word.
pub const MAX_CHUNK: usize = 256;
/// Job chunks the device buffers (the most credit it grants). With 256-byte chunks this
/// is 2 KiB of RAM, which covers the USB round trip at flash-write speed.
pub const WINDOW: usize = 8;
/// Largest encoded message (header + body), bytes: a full config (8 inlets) is about
/// 700, a job header at most 512 (`job::MAX_HEADER_LEN`).
pub const MAX_PAYLOAD: usize = 1024;
/// Largest frame on the wire without its zero delimiter: payload, CRC, COBS overhead.
pub const MAX_FRAME: usize = cobs::max_encoding_length(MAX_PAYLOAD + 4);
/// Room for a text in refusals (config errors, reasons), bytes.
pub const TEXT_LEN: usize = 96;
/// USB vendor id of the board (pid.codes, the open-source hardware vendor id).
pub const USB_VID: u16 = 0x1209;
/// USB product id of the board. pid.codes' test id: a product that ships should get its
/// own from pid.codes; the host also checks the product string.
pub const USB_PID: u16 = 0x0001;
/// USB product string; the host's auto-detection looks for it.
pub const USB_PRODUCT: &str = "dollop controller";
/// The device counts the link as lost when no frame came for this long while a job runs.
/// The host polls at least every `POLL_MS` while it follows a print.
pub const LINK_TIMEOUT_MS: u32 = 3_000;
/// Longest gap between the host's requests while it follows a print, ms.
pub const POLL_MS: u32 = 250;
