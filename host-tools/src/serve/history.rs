//! The print history: one record per print that ended on a board (job, config hash,
//! start, end, outcome, duration), the last `KEEP_RECORDS` in memory and, with `--data
//! DIR`, appended to `DIR/history.jsonl` and read back at start (a line that does not
//! parse is skipped and counted, never fatal). Statistics over it for the page. This file
//! stops at records: the board's worker says when a print ended and how.

use super::lock::lock;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Records kept in memory (and shown); the file keeps them all.
pub const KEEP_RECORDS: usize = 500;

/// One print.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Record {
    /// The board's number and name.
    pub board: usize,
    /// Its name.
    pub board_name: String,
    /// The job's name.
    pub job: String,
    /// The machine config's hash (as the board checks it), hex.
    pub config_hash: String,
    /// Start and end, seconds since 1970.
    pub started_unix_s: f64,
    /// End.
    pub ended_unix_s: f64,
    /// `finished`, `aborted` or `halted`.
    pub outcome: String,
    /// Seconds printing (pauses left out).
    pub printing_s: f64,
    /// Commands done, of `commands`.
    pub command: u32,
    /// Commands in the job.
    pub commands: u32,
}

/// Totals over the history.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Stats {
    /// Prints.
    pub prints: usize,
    /// Of them finished.
    pub finished: usize,
    /// Aborted.
    pub aborted: usize,
    /// Halted (a fault).
    pub halted: usize,
    /// Seconds printing, all prints.
    pub printing_s: f64,
}

/// The history.
pub struct History {
    file: Option<PathBuf>,
    records: Mutex<Vec<Record>>,
    /// Lines of the file that did not parse when it was read.
    pub skipped: usize,
}

impl History {
    /// In memory only.
    pub fn memory() -> Self {
        History {
            file: None,
            records: Mutex::new(Vec::new()),
            skipped: 0,
        }
    }

    /// Reads `dir/history.jsonl` (absent: empty) and appends there from now on.
    pub fn open(dir: &Path) -> anyhow::Result<Self> {
        let file = dir.join("history.jsonl");
        let text = match std::fs::read_to_string(&file) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
            Err(e) => anyhow::bail!("cannot read the print history {}: {e}", file.display()),
        };
        let mut records = Vec::new();
        let mut skipped = 0;
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            match serde_json::from_str::<Record>(line) {
                Ok(r) => records.push(r),
                Err(_) => skipped += 1,
            }
        }
        let over = records.len().saturating_sub(KEEP_RECORDS);
        records.drain(..over);
        Ok(History {
            file: Some(file),
            records: Mutex::new(records),
            skipped,
        })
    }

    /// Adds a record (and appends it to the file); a write failure is returned for the
    /// board's message, the record is kept in memory regardless.
    pub fn add(&self, r: Record) -> Result<(), String> {
        let line = serde_json::to_string(&r).map_err(|e| e.to_string())?;
        {
            let mut rs = lock(&self.records);
            rs.push(r);
            let over = rs.len().saturating_sub(KEEP_RECORDS);
            rs.drain(..over);
        }
        let Some(path) = &self.file else {
            return Ok(());
        };
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .and_then(|mut f| writeln!(f, "{line}"))
            .map_err(|e| format!("cannot write the print history {}: {e}", path.display()))
    }

    /// The records, newest last.
    pub fn list(&self) -> Vec<Record> {
        lock(&self.records).clone()
    }

    /// Totals.
    pub fn stats(&self) -> Stats {
        let rs = lock(&self.records);
        let mut s = Stats {
            prints: rs.len(),
            ..Default::default()
        };
        for r in rs.iter() {
            match r.outcome.as_str() {
                "finished" => s.finished += 1,
                "aborted" => s.aborted += 1,
                _ => s.halted += 1,
            }
            s.printing_s += r.printing_s;
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(outcome: &str, printing_s: f64) -> Record {
        Record {
            board: 0,
            board_name: "simulated board".into(),
            job: "logo.png".into(),
            config_hash: "00ff".into(),
            started_unix_s: 1.0,
            ended_unix_s: 2.0 + printing_s,
            outcome: outcome.into(),
            printing_s,
            command: 3,
            commands: 9,
        }
    }

    #[test]
    fn records_survive_a_restart_and_a_bad_line_is_skipped() {
        let dir = tempfile::tempdir().expect("folder");
        let h = History::open(dir.path()).expect("opens empty");
        h.add(record("finished", 60.0)).expect("written");
        h.add(record("aborted", 15.0)).expect("written");
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(dir.path().join("history.jsonl"))
            .expect("file");
        writeln!(f, "{{not json").expect("write");
        drop(f);
        let again = History::open(dir.path()).expect("reads");
        assert_eq!(again.skipped, 1);
        assert_eq!(
            again.list(),
            vec![record("finished", 60.0), record("aborted", 15.0)]
        );
        let s = again.stats();
        assert_eq!((s.prints, s.finished, s.aborted, s.halted), (2, 1, 1, 0));
        assert_eq!(s.printing_s, 75.0);
    }
}
