//! A job file (`.dlp`) in memory as the link sends it: header and body, checked on load
//! (preamble CRC, body length, body CRC, command count) so a corrupt file is refused
//! before anything is sent; plus a synthetic job maker for link tests and benchmarks.

use crate::slicer::job_file;
use dollop::job::{self, BodyDecoder, JobError, JobHeader};
use dollop::{Command, Config};
use std::path::Path;

/// A checked job.
#[derive(Clone, Debug)]
pub struct JobFile {
    /// The header.
    pub header: JobHeader,
    /// The body: postcard commands back to back.
    pub body: Vec<u8>,
}

impl JobFile {
    /// Parses and checks a whole job file.
    pub fn parse(bytes: &[u8]) -> Result<JobFile, JobError> {
        let (header, n) = job::decode_preamble(bytes)?;
        let body = &bytes[n..];
        let mut d = BodyDecoder::new(&header);
        d.feed(body, |_| Ok::<(), ()>(()))?
            .map_err(|()| JobError::BufferTooSmall)?;
        d.finish()?;
        Ok(JobFile {
            header,
            body: body.to_vec(),
        })
    }

    /// Reads and checks a job file.
    pub fn read(path: &Path) -> anyhow::Result<JobFile> {
        let bytes = std::fs::read(path)
            .map_err(|e| anyhow::anyhow!("cannot read job {}: {e}", path.display()))?;
        JobFile::parse(&bytes).map_err(|e| anyhow::anyhow!("job {}: {e}", path.display()))
    }

    /// Builds a job from commands (the last should be `End`), as the slicer encodes one.
    pub fn build(
        config: &Config,
        start_um: [i32; 3],
        initial: u8,
        commands: &[Command],
    ) -> JobFile {
        let (header, body) = job_file::encode(commands, start_um, initial, config);
        JobFile { header, body }
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        job_file::job_bytes(&self.header, &self.body)
    }

    /// Print segments the header announces.
    pub fn segments(&self) -> u32 {
        self.header.print_segments
    }
}

/// A job of `segments` short print segments in rows (two materials alternating every
/// few segments), inside `config`'s travel: for link tests and benchmarks.
pub fn zigzag(config: &Config, segments: u32) -> JobFile {
    let m = &config.motion;
    let mid = |a: usize| ((m.travel_min_mm[a] + m.travel_max_mm[a]) * 500.0) as i32;
    let start = [
        mid(0) - 20_000,
        mid(1) - 20_000,
        (m.travel_min_mm[2] * 1000.0) as i32 + 600,
    ];
    let inlets = config.inlets.len().clamp(1, dollop::DEFAULT_INLETS) as u8;
    let per_row = 80u32;
    let mut cmds = Vec::with_capacity(segments as usize + 2);
    cmds.push(Command::Travel {
        x: start[0],
        y: start[1],
        z: start[2],
    });
    let mut row = 0u32;
    let mut i = 0u32;
    while i < segments {
        let dir = if row.is_multiple_of(2) { 1 } else { -1 };
        for k in 0..per_row.min(segments - i) {
            cmds.push(Command::Print {
                dx: dir * 500,
                dy: 0,
                material: (((i + k) / 7) % inlets as u32) as u8,
            });
        }
        i += per_row.min(segments - i);
        row += 1;
        if row.is_multiple_of(50) {
            // A new layer every 50 rows keeps the job inside a 40 mm square.
            cmds.push(Command::Layer {
                z: start[2] + (row / 50) as i32 * 600,
            });
            cmds.push(Command::Travel {
                x: start[0],
                y: start[1],
                z: start[2] + (row / 50) as i32 * 600,
            });
        } else if i < segments {
            cmds.push(Command::Print {
                dx: 0,
                dy: 800,
                material: ((i / 7) % inlets as u32) as u8,
            });
        }
    }
    cmds.push(Command::End);
    JobFile::build(config, start, 0, &cmds)
}
