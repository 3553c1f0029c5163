//! Job files on the host: the core's `.dlp` format (`dollop::job`) filled in completely
//! (config hash, materials, bounds, start, counts, body CRC), written atomically and read
//! back with every check the firmware makes. The format itself is the core's.

use super::error::SliceError;
use super::output::write_bytes;
use dollop::config::Config;
use dollop::job::{
    self, body_crc, config_hash, decode_preamble, encode_command, encode_preamble, BodyDecoder,
    JobError, JobHeader, MaterialEntry, MAX_COMMAND_LEN, MAX_HEADER_LEN,
};
use dollop::Command;
use std::path::Path;

/// Lowest and highest corner of everything the commands visit from `start_um`, um.
pub fn bounds(commands: &[Command], start_um: [i32; 3]) -> ([i32; 3], [i32; 3]) {
    let mut at = [start_um[0] as i64, start_um[1] as i64, start_um[2] as i64];
    let mut lo = at;
    let mut hi = at;
    for c in commands {
        match *c {
            Command::Print { dx, dy, .. } => {
                at[0] += dx as i64;
                at[1] += dy as i64;
            }
            Command::Travel { x, y, z } => at = [x as i64, y as i64, z as i64],
            Command::Layer { z } => at[2] = z as i64,
            Command::Dwell { .. } | Command::End | Command::Section { .. } => continue,
        }
        for a in 0..3 {
            lo[a] = lo[a].min(at[a]);
            hi[a] = hi[a].max(at[a]);
        }
    }
    let clamp = |v: i64| v.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
    (lo.map(clamp), hi.map(clamp))
}

/// The body: postcard commands back to back.
fn encode_body(commands: &[Command]) -> Vec<u8> {
    let mut body = Vec::with_capacity(commands.len() * 6);
    let mut buf = [0u8; MAX_COMMAND_LEN];
    for c in commands {
        // MAX_COMMAND_LEN bounds every command's encoding, so this cannot fail.
        if let Ok(b) = encode_command(c, &mut buf) {
            body.extend_from_slice(b);
        }
    }
    body
}

/// The complete header for `commands` (already encoded as `body`) sliced for `config`.
fn header_for(
    commands: &[Command],
    body: &[u8],
    start_um: [i32; 3],
    initial_material: u8,
    config: &Config,
) -> JobHeader {
    let mut used = 1u32 << initial_material.min(31);
    let mut segments = 0u32;
    for c in commands {
        if let Command::Print { material, .. } = c {
            used |= 1 << (*material).min(31);
            segments += 1;
        }
    }
    let mut materials = heapless::Vec::new();
    for (i, inlet) in config.inlets.iter().enumerate() {
        if used & (1 << i) != 0 {
            // The table has room for every configured inlet.
            let _ = materials.push(MaterialEntry {
                inlet: i as u8,
                name: inlet.material.clone(),
            });
        }
    }
    let (lo, hi) = bounds(commands, start_um);
    JobHeader {
        // Version 1 unless the job needs more, so older boards take what they can print.
        format_version: job::version_for(commands),
        config_hash: config_hash(config),
        materials,
        bounds_min_um: lo,
        bounds_max_um: hi,
        start_um,
        initial_material,
        print_segments: segments,
        commands: commands.len() as u32,
        body_len: body.len() as u32,
        body_crc: body_crc(body),
    }
}

/// The whole file: preamble then body.
pub fn job_bytes(header: &JobHeader, body: &[u8]) -> Vec<u8> {
    let mut pre = [0u8; MAX_HEADER_LEN + 16];
    // Headers are far below MAX_HEADER_LEN (8 material names of 24 bytes and a few
    // varints), so encoding cannot run out of room.
    let pre = encode_preamble(header, &mut pre)
        .map(|p| p.to_vec())
        .unwrap_or_default();
    let mut out = Vec::with_capacity(pre.len() + body.len());
    out.extend_from_slice(&pre);
    out.extend_from_slice(body);
    out
}

/// `commands` (from `start_um`, primed with `initial_material`) encoded for `config`: the
/// complete header and the body. Every job the host makes is encoded here.
pub fn encode(
    commands: &[Command],
    start_um: [i32; 3],
    initial_material: u8,
    config: &Config,
) -> (JobHeader, Vec<u8>) {
    let body = encode_body(commands);
    let header = header_for(commands, &body, start_um, initial_material, config);
    (header, body)
}

/// Encodes `job` for `config` and writes it atomically to `path`.
pub fn write(path: &Path, job: &dollop_sim::Job, config: &Config) -> Result<(), SliceError> {
    let (header, body) = encode(&job.commands, job.start_um, job.initial_material, config);
    write_bytes(path, &job_bytes(&header, &body))
}

/// Decodes a whole job held in memory, checking magic, version, CRCs, length and count.
pub fn decode_job(bytes: &[u8]) -> Result<(JobHeader, Vec<Command>), JobError> {
    let (header, n) = decode_preamble(bytes)?;
    let mut d = BodyDecoder::new(&header);
    let mut cmds = Vec::with_capacity(header.commands.min(1 << 24) as usize);
    d.feed(&bytes[n..], |c| -> Result<(), ()> {
        cmds.push(c);
        Ok(())
    })?
    .ok();
    d.finish()?;
    Ok((header, cmds))
}

/// Reads and checks a job file.
pub fn read_job(path: &Path) -> Result<(JobHeader, Vec<Command>), SliceError> {
    let bytes = std::fs::read(path).map_err(|e| SliceError::read(path, e))?;
    decode_job(&bytes).map_err(|problem| SliceError::Job {
        path: path.to_path_buf(),
        problem,
    })
}

/// Re-export so callers need not name the core's module.
pub use job::MAGIC;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_follow_prints_travels_and_layers() {
        let cmds = [
            Command::Travel {
                x: 1000,
                y: 2000,
                z: 800,
            },
            Command::Print {
                dx: 5000,
                dy: -500,
                material: 0,
            },
            Command::Layer { z: 1400 },
            Command::End,
        ];
        let (lo, hi) = bounds(&cmds, [0, 0, 0]);
        assert_eq!(lo, [0, 0, 0]);
        assert_eq!(hi, [6000, 2000, 1400]);
    }
}
