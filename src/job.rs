//! The compact job file (`.dlp`): a magic, a postcard header (format version, machine
//! config hash, material table, bounds, counts), a header CRC, then the body: postcard
//! `Command`s back to back, guarded by a CRC-32 in the header. Decoding is streaming and
//! heap-free so the firmware can take a job in chunks; building jobs is the host's.

use crate::command::Command;
use crate::config::{Config, MATERIAL_NAME_LEN, MAX_CONFIG_INLETS};
use serde::{Deserialize, Serialize};

/// First bytes of every job file.
pub const MAGIC: [u8; 4] = *b"DLOP";
/// Version of the header and body encoding of a job with the version 1 commands only
/// (print, travel, layer, dwell, end): every job without a `Command::Section`. Jobs are
/// written at the lowest version that holds their commands (`version_for`), so a board or
/// tool that reads only version 1 still takes them.
pub const FORMAT_VERSION: u16 = 1;
/// Version of a job with `Command::Section` (per-bead sections): version 1's header and
/// commands, plus that one command. A version 1 reader refuses it by its version.
pub const FORMAT_VERSION_SECTIONS: u16 = 2;
/// Version of a job with a `Command::Section` inside a bead (right after a print command):
/// version 2's encoding, whose executor took sections between beads only. A board built
/// before it would have taken such a job and faulted mid-print (`SectionInBead`, the bead
/// half laid); by its version it refuses the job before the first move.
pub const FORMAT_VERSION_BEAD_SECTIONS: u16 = 3;
/// Highest version this build reads (it reads every version from 1).
pub const FORMAT_VERSION_MAX: u16 = FORMAT_VERSION_BEAD_SECTIONS;

/// Whether this build reads jobs of format `version`.
pub fn reads_version(version: u16) -> bool {
    (FORMAT_VERSION..=FORMAT_VERSION_MAX).contains(&version)
}

/// The format version a job with these commands is written as: the lowest that holds them.
pub fn version_for<'a>(commands: impl IntoIterator<Item = &'a Command>) -> u16 {
    let mut version = FORMAT_VERSION;
    // Whether a bead is open: the last command other than a section was a print.
    let mut in_bead = false;
    for c in commands {
        match c {
            Command::Section { .. } if in_bead => return FORMAT_VERSION_BEAD_SECTIONS,
            Command::Section { .. } => version = FORMAT_VERSION_SECTIONS,
            Command::Print { .. } => in_bead = true,
            _ => in_bead = false,
        }
    }
    version
}
/// Longest encoded header accepted, bytes.
pub const MAX_HEADER_LEN: usize = 512;
/// Longest encoded command, bytes (variant + three zigzag varints).
pub const MAX_COMMAND_LEN: usize = 16;

/// CRC used for headers, bodies and configs: CRC-32/ISO-HDLC (the zip/PNG one).
pub static CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// One material the job uses.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct MaterialEntry {
    /// Inlet index.
    pub inlet: u8,
    /// Material name, as in the config the job was sliced for.
    pub name: heapless::String<MATERIAL_NAME_LEN>,
}

/// What a job file says about itself.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct JobHeader {
    /// `FORMAT_VERSION` of the writer.
    pub format_version: u16,
    /// `config_hash` of the machine config the job was sliced for.
    pub config_hash: u32,
    /// Materials used.
    pub materials: heapless::Vec<MaterialEntry, MAX_CONFIG_INLETS>,
    /// Lowest corner of everything the job visits, micrometres.
    pub bounds_min_um: [i32; 3],
    /// Highest corner, micrometres.
    pub bounds_max_um: [i32; 3],
    /// Where the head must stand when the job begins, micrometres.
    pub start_um: [i32; 3],
    /// Material the channel must be primed with.
    pub initial_material: u8,
    /// Print segments in the body.
    pub print_segments: u32,
    /// Commands in the body (including the final `End`).
    pub commands: u32,
    /// Body length, bytes.
    pub body_len: u32,
    /// CRC-32 of the body.
    pub body_crc: u32,
}

/// Why a job file (or stream) is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobError {
    /// Does not start with "DLOP".
    BadMagic,
    /// Ends before the header does.
    TruncatedHeader,
    /// Header longer than `MAX_HEADER_LEN`.
    HeaderTooLong(usize),
    /// Header bytes fail their CRC.
    HeaderCrc,
    /// Header bytes do not decode.
    HeaderDecode,
    /// Written by another format version.
    Version {
        /// Version in the file.
        found: u16,
        /// Highest version this build reads (it reads every one from 1).
        supported: u16,
    },
    /// Body shorter or longer than the header says.
    BodyLength {
        /// From the header.
        expected: u32,
        /// Present.
        found: u64,
    },
    /// Body fails its CRC.
    BodyCrc,
    /// A command in the body does not decode.
    CommandDecode {
        /// Byte offset in the body.
        offset: u32,
    },
    /// The body holds a different number of commands than the header says.
    CommandCount {
        /// From the header.
        expected: u32,
        /// Decoded.
        found: u32,
    },
    /// An encoding buffer was too small.
    BufferTooSmall,
}

impl core::fmt::Display for JobError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            JobError::BadMagic => write!(f, "not a dollop job file (no DLOP magic)"),
            JobError::TruncatedHeader => write!(f, "job file ends inside its header"),
            JobError::HeaderTooLong(n) => write!(f, "job header of {n} bytes is too long"),
            JobError::HeaderCrc => write!(f, "job header is corrupt (CRC mismatch)"),
            JobError::HeaderDecode => write!(f, "job header does not decode"),
            JobError::Version { found, supported } => write!(
                f,
                "job format version {found}, but this build reads versions 1 to {supported}; update dollop, or re-slice the design with this one"
            ),
            JobError::BodyLength { expected, found } => write!(
                f,
                "job body is {found} bytes but the header says {expected} (truncated file?)"
            ),
            JobError::BodyCrc => write!(f, "job body is corrupt (CRC mismatch)"),
            JobError::CommandDecode { offset } => {
                write!(f, "job command at body byte {offset} does not decode")
            }
            JobError::CommandCount { expected, found } => write!(
                f,
                "job body holds {found} commands but the header says {expected}"
            ),
            JobError::BufferTooSmall => write!(f, "buffer too small for the job"),
        }
    }
}

/// Hash identifying a machine config: CRC-32 of its postcard encoding, the `[pause]`
/// section left out where it is the default. A park position does not change what a job
/// prints, and configs written before the section existed keep their hash (and the jobs
/// sliced for them stay loadable); a non-default section still changes it, so that the
/// host uploads a config whose park changed.
pub fn config_hash(config: &Config) -> u32 {
    let mut buf = [0u8; 2048];
    // A postcard struct is its fields back to back: the tuple encodes as the config did
    // before `pause` was added.
    let head = (
        &config.channel,
        &config.motion,
        &config.control,
        &config.inlets,
    );
    let Ok(n) = postcard::to_slice(&head, &mut buf).map(|b| b.len()) else {
        return 0;
    };
    let n = if config.pause == crate::config::PauseConfig::default() {
        n
    } else {
        match postcard::to_slice(&config.pause, &mut buf[n..]) {
            Ok(b) => n + b.len(),
            Err(_) => return 0,
        }
    };
    CRC.checksum(&buf[..n])
}

/// Encodes one command into `buf`, returning the bytes used.
pub fn encode_command<'a>(cmd: &Command, buf: &'a mut [u8]) -> Result<&'a mut [u8], JobError> {
    postcard::to_slice(cmd, buf).map_err(|_| JobError::BufferTooSmall)
}

/// Writes the preamble (magic, header length, header, header CRC) into `buf`.
pub fn encode_preamble<'a>(header: &JobHeader, buf: &'a mut [u8]) -> Result<&'a [u8], JobError> {
    let mut tmp = [0u8; MAX_HEADER_LEN];
    let h = postcard::to_slice(header, &mut tmp).map_err(|_| JobError::BufferTooSmall)?;
    let n = 4 + 2 + h.len() + 4;
    if buf.len() < n {
        return Err(JobError::BufferTooSmall);
    }
    buf[..4].copy_from_slice(&MAGIC);
    buf[4..6].copy_from_slice(&(h.len() as u16).to_le_bytes());
    buf[6..6 + h.len()].copy_from_slice(h);
    buf[6 + h.len()..n].copy_from_slice(&CRC.checksum(h).to_le_bytes());
    Ok(&buf[..n])
}

/// Reads the preamble at the start of `bytes`: the header and the preamble's length.
pub fn decode_preamble(bytes: &[u8]) -> Result<(JobHeader, usize), JobError> {
    if bytes.len() < 4 {
        return Err(JobError::TruncatedHeader);
    }
    if bytes[..4] != MAGIC {
        return Err(JobError::BadMagic);
    }
    if bytes.len() < 6 {
        return Err(JobError::TruncatedHeader);
    }
    let len = u16::from_le_bytes([bytes[4], bytes[5]]) as usize;
    if len > MAX_HEADER_LEN {
        return Err(JobError::HeaderTooLong(len));
    }
    let end = 6 + len + 4;
    if bytes.len() < end {
        return Err(JobError::TruncatedHeader);
    }
    let h = &bytes[6..6 + len];
    let crc = u32::from_le_bytes([
        bytes[6 + len],
        bytes[7 + len],
        bytes[8 + len],
        bytes[9 + len],
    ]);
    if CRC.checksum(h) != crc {
        return Err(JobError::HeaderCrc);
    }
    // The version is the header's first field: check it before the rest can mislead.
    let (version, _) = postcard::take_from_bytes::<u16>(h).map_err(|_| JobError::HeaderDecode)?;
    if !reads_version(version) {
        return Err(JobError::Version {
            found: version,
            supported: FORMAT_VERSION_MAX,
        });
    }
    let header: JobHeader = postcard::from_bytes(h).map_err(|_| JobError::HeaderDecode)?;
    Ok((header, end))
}

/// Streaming decoder for a job body arriving in chunks of any size: feed bytes, take
/// commands. Checks the body CRC, length and command count at `finish`.
#[derive(Clone)]
pub struct BodyDecoder {
    carry: [u8; MAX_COMMAND_LEN],
    carry_len: usize,
    digest: crc::Digest<'static, u32>,
    offset: u32,
    commands: u32,
    expected_len: u32,
    expected_crc: u32,
    expected_commands: u32,
    /// The body may hold `Command::Section` (format version 2 on).
    sections: bool,
}

impl BodyDecoder {
    /// A decoder for the body `header` describes.
    pub fn new(header: &JobHeader) -> Self {
        BodyDecoder {
            carry: [0; MAX_COMMAND_LEN],
            carry_len: 0,
            digest: CRC.digest(),
            offset: 0,
            commands: 0,
            expected_len: header.body_len,
            expected_crc: header.body_crc,
            expected_commands: header.commands,
            sections: header.format_version >= FORMAT_VERSION_SECTIONS,
        }
    }

    /// A command of a later version than the header's is corrupt data, as any other
    /// undecodable command.
    fn allowed(&self, cmd: &Command) -> Result<(), JobError> {
        if !self.sections && matches!(cmd, Command::Section { .. }) {
            return Err(JobError::CommandDecode {
                offset: self.offset,
            });
        }
        Ok(())
    }

    /// Decodes the commands that `chunk` completes, calling `sink` for each in order.
    /// Bytes of a command split across chunks are carried over. On error nothing more
    /// should be fed.
    pub fn feed<E>(
        &mut self,
        chunk: &[u8],
        mut sink: impl FnMut(Command) -> Result<(), E>,
    ) -> Result<Result<(), E>, JobError> {
        if self.offset as u64 + chunk.len() as u64 > self.expected_len as u64 {
            return Err(JobError::BodyLength {
                expected: self.expected_len,
                found: self.offset as u64 + chunk.len() as u64,
            });
        }
        self.digest.update(chunk);
        let mut rest = chunk;
        // Finish a command split over the previous chunk.
        while self.carry_len > 0 && !rest.is_empty() {
            let take = (MAX_COMMAND_LEN - self.carry_len).min(rest.len());
            let mut tmp = [0u8; MAX_COMMAND_LEN];
            tmp[..self.carry_len].copy_from_slice(&self.carry[..self.carry_len]);
            tmp[self.carry_len..self.carry_len + take].copy_from_slice(&rest[..take]);
            let avail = self.carry_len + take;
            match postcard::take_from_bytes::<Command>(&tmp[..avail]) {
                Ok((cmd, left)) => {
                    self.allowed(&cmd)?;
                    let used = avail - left.len();
                    let from_rest = used - self.carry_len;
                    rest = &rest[from_rest..];
                    self.offset += used as u32;
                    self.carry_len = 0;
                    self.commands += 1;
                    if let Err(e) = sink(cmd) {
                        return Ok(Err(e));
                    }
                }
                Err(postcard::Error::DeserializeUnexpectedEnd) if avail < MAX_COMMAND_LEN => {
                    self.carry[self.carry_len..avail].copy_from_slice(&rest[..take]);
                    self.carry_len = avail;
                    return Ok(Ok(()));
                }
                Err(_) => {
                    return Err(JobError::CommandDecode {
                        offset: self.offset,
                    })
                }
            }
        }
        while !rest.is_empty() {
            match postcard::take_from_bytes::<Command>(rest) {
                Ok((cmd, left)) => {
                    self.allowed(&cmd)?;
                    self.offset += (rest.len() - left.len()) as u32;
                    rest = left;
                    self.commands += 1;
                    if let Err(e) = sink(cmd) {
                        return Ok(Err(e));
                    }
                }
                Err(postcard::Error::DeserializeUnexpectedEnd) if rest.len() < MAX_COMMAND_LEN => {
                    self.carry[..rest.len()].copy_from_slice(rest);
                    self.carry_len = rest.len();
                    break;
                }
                Err(_) => {
                    return Err(JobError::CommandDecode {
                        offset: self.offset,
                    })
                }
            }
        }
        Ok(Ok(()))
    }

    /// Bytes consumed so far (including carried ones).
    pub fn bytes_fed(&self) -> u32 {
        self.offset + self.carry_len as u32
    }

    /// Checks length, CRC and count once the whole body was fed.
    pub fn finish(&self) -> Result<(), JobError> {
        let fed = self.bytes_fed();
        if fed != self.expected_len || self.carry_len != 0 {
            if self.carry_len != 0 && fed == self.expected_len {
                return Err(JobError::CommandDecode {
                    offset: self.offset,
                });
            }
            return Err(JobError::BodyLength {
                expected: self.expected_len,
                found: fed as u64,
            });
        }
        if self.digest.clone().finalize() != self.expected_crc {
            return Err(JobError::BodyCrc);
        }
        if self.commands != self.expected_commands {
            return Err(JobError::CommandCount {
                expected: self.expected_commands,
                found: self.commands,
            });
        }
        Ok(())
    }
}

/// CRC-32 of a whole body.
pub fn body_crc(body: &[u8]) -> u32 {
    CRC.checksum(body)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn sample() -> (JobHeader, Vec<u8>, Vec<Command>) {
        let cmds = vec![
            Command::Travel {
                x: 10_000,
                y: 10_000,
                z: 600,
            },
            Command::Print {
                dx: 5000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: 3000,
                dy: 0,
                material: 1,
            },
            Command::Print {
                dx: 0,
                dy: 800,
                material: 1,
            },
            Command::Print {
                dx: -8000,
                dy: 0,
                material: 0,
            },
            Command::Layer { z: 1200 },
            Command::Dwell { ms: 250 },
            Command::End,
        ];
        let mut body = Vec::new();
        for c in &cmds {
            let mut b = [0u8; MAX_COMMAND_LEN];
            body.extend_from_slice(encode_command(c, &mut b).unwrap());
        }
        let header = JobHeader {
            format_version: FORMAT_VERSION,
            config_hash: 0x1234_5678,
            materials: heapless::Vec::new(),
            bounds_min_um: [10_000, 10_000, 600],
            bounds_max_um: [18_000, 10_800, 1200],
            start_um: [10_000, 10_000, 600],
            initial_material: 0,
            print_segments: 4,
            commands: cmds.len() as u32,
            body_len: body.len() as u32,
            body_crc: body_crc(&body),
        };
        (header, body, cmds)
    }

    /// The commands `body` decodes to, fed `chunk` bytes at a time.
    fn decode_in_chunks(h: &JobHeader, body: &[u8], chunk: usize) -> Vec<Command> {
        let mut d = BodyDecoder::new(h);
        let mut got = Vec::new();
        for c in body.chunks(chunk) {
            d.feed(c, |cmd| -> Result<(), ()> {
                got.push(cmd);
                Ok(())
            })
            .unwrap()
            .unwrap();
        }
        d.finish().unwrap();
        got
    }

    #[test]
    fn chunked_decoding_gives_the_commands_for_every_chunk_size() {
        let (h, body, cmds) = sample();
        for chunk in 1..=body.len() {
            assert_eq!(
                decode_in_chunks(&h, &body, chunk),
                cmds,
                "chunk size {chunk}"
            );
        }
    }

    #[test]
    fn preamble_round_trips_and_corruption_is_named() {
        let (h, _, _) = sample();
        let mut buf = [0u8; 600];
        let pre = encode_preamble(&h, &mut buf).unwrap().to_vec();
        let (back, n) = decode_preamble(&pre).unwrap();
        assert_eq!(back, h);
        assert_eq!(n, pre.len());
        let mut bad = pre.clone();
        bad[8] ^= 0x40;
        assert_eq!(decode_preamble(&bad), Err(JobError::HeaderCrc));
        assert_eq!(decode_preamble(&pre[..7]), Err(JobError::TruncatedHeader));
        assert_eq!(decode_preamble(b"GIF89a..."), Err(JobError::BadMagic));
    }

    #[test]
    fn corrupt_or_short_bodies_are_refused() {
        let (h, body, _) = sample();
        let mut bad = body.clone();
        bad[3] ^= 1;
        let mut d = BodyDecoder::new(&h);
        let _ = d.feed(&bad, |_| -> Result<(), ()> { Ok(()) });
        assert!(d.finish().is_err());
        let mut d = BodyDecoder::new(&h);
        d.feed(&body[..body.len() - 2], |_| -> Result<(), ()> { Ok(()) })
            .unwrap()
            .unwrap();
        assert!(matches!(d.finish(), Err(JobError::BodyLength { .. })));
        let mut d = BodyDecoder::new(&h);
        let mut long = body.clone();
        long.push(0);
        assert!(matches!(
            d.feed(&long, |_| -> Result<(), ()> { Ok(()) }),
            Err(JobError::BodyLength { .. })
        ));
    }

    /// `sample()` with a section before its second bead, as version `version`.
    fn with_section(version: u16) -> (JobHeader, Vec<u8>, Vec<Command>) {
        let (mut h, _, mut cmds) = sample();
        cmds.insert(6, Command::Section { um2: 520_000 });
        cmds.insert(
            7,
            Command::Print {
                dx: 800,
                dy: 0,
                material: 0,
            },
        );
        let mut body = Vec::new();
        for c in &cmds {
            let mut b = [0u8; MAX_COMMAND_LEN];
            body.extend_from_slice(encode_command(c, &mut b).unwrap());
        }
        h.format_version = version;
        h.commands = cmds.len() as u32;
        h.body_len = body.len() as u32;
        h.body_crc = body_crc(&body);
        (h, body, cmds)
    }

    /// A section between beads needs version 2; one right after a print (inside a bead,
    /// which a version 2 board's executor refused mid-print) needs version 3, so that such
    /// a board refuses the job by its version before the first move.
    #[test]
    fn a_section_inside_a_bead_is_version_3() {
        let p = Command::Print {
            dx: 1000,
            dy: 0,
            material: 0,
        };
        let t = Command::Travel {
            x: 0,
            y: 1000,
            z: 600,
        };
        let sec = Command::Section { um2: 500_000 };
        assert_eq!(version_for(&[p, p, t, p]), FORMAT_VERSION);
        assert_eq!(version_for(&[sec, p, t, sec, p]), FORMAT_VERSION_SECTIONS);
        assert_eq!(version_for(&[p, t, sec, sec, p]), FORMAT_VERSION_SECTIONS);
        assert_eq!(version_for(&[sec, p, sec, p]), FORMAT_VERSION_BEAD_SECTIONS);
        assert_eq!(version_for(&[p, sec, t, p]), FORMAT_VERSION_BEAD_SECTIONS);
        assert!(reads_version(FORMAT_VERSION_BEAD_SECTIONS));
        assert!(!reads_version(FORMAT_VERSION_BEAD_SECTIONS + 1));
    }

    #[test]
    fn a_version_2_body_holds_sections_and_a_version_1_body_may_not() {
        let (h, body, cmds) = with_section(FORMAT_VERSION_SECTIONS);
        assert_eq!(version_for(&cmds), FORMAT_VERSION_SECTIONS);
        assert_eq!(version_for(&sample().2), FORMAT_VERSION);
        for chunk in [1, 3, body.len()] {
            assert_eq!(
                decode_in_chunks(&h, &body, chunk),
                cmds,
                "chunk size {chunk}"
            );
        }
        // The same body under a version 1 header: the section is where it stops.
        let (h1, body1, _) = with_section(FORMAT_VERSION);
        for chunk in [1, body1.len()] {
            let mut d = BodyDecoder::new(&h1);
            let mut n = 0;
            let mut err = None;
            for c in body1.chunks(chunk) {
                match d.feed(c, |_| -> Result<(), ()> {
                    n += 1;
                    Ok(())
                }) {
                    Ok(_) => {}
                    Err(e) => {
                        err = Some(e);
                        break;
                    }
                }
            }
            assert!(
                matches!(err, Some(JobError::CommandDecode { .. })),
                "chunk {chunk}: {err:?}"
            );
            assert_eq!(n, 6, "the commands before the section");
        }
    }

    #[test]
    fn versions_past_this_build_are_refused_by_name() {
        for (v, ok) in [(0, false), (1, true), (2, true), (3, true), (4, false)] {
            let (mut h, _, _) = sample();
            h.format_version = v;
            let mut buf = [0u8; 600];
            let pre = encode_preamble(&h, &mut buf).unwrap().to_vec();
            match decode_preamble(&pre) {
                Ok((back, _)) => assert!(ok && back == h, "version {v}"),
                Err(e) => {
                    assert!(!ok, "version {v}: {e}");
                    assert_eq!(
                        e,
                        JobError::Version {
                            found: v,
                            supported: 3
                        }
                    );
                    assert!(e.to_string().contains("reads versions 1 to 3"), "{e}");
                }
            }
        }
    }

    #[test]
    fn garbage_never_panics() {
        let (h, _, _) = sample();
        let mut seed = 0x2545_f491u32;
        for _ in 0..2000 {
            let mut v = Vec::new();
            for _ in 0..(seed % 64) {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                v.push(seed as u8);
            }
            let _ = decode_preamble(&v);
            let mut hh = h.clone();
            hh.body_len = v.len() as u32;
            let mut d = BodyDecoder::new(&hh);
            let _ = d.feed(&v, |_| -> Result<(), ()> { Ok(()) });
            let _ = d.finish();
        }
    }
}
