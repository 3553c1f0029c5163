//! Measurement tables: reads a CSV file (optional header row, `#` comments, spaces trimmed)
//! into cells that remember their line, within stated limits on its size and rows, and
//! hands out checked numeric or text columns. What the columns mean is each calibration's
//! business.

use super::error::CalOption;
use super::CalError;
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// How much of a measurement file is read. A rheometer sweep has tens of points and a
/// scale logging at 100 Hz for an hour 360 000; a million rows parse to about 150 MB of
/// cells, which keeps a calibration well under the 1 GiB the host tools allow themselves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most data rows (`--max-rows`).
    pub max_rows: usize,
    /// Largest file, MiB (`--max-csv-mb`): bounds one giant line, which has no rows to count.
    pub max_mib: u64,
}

/// Default `--max-rows`.
pub const MAX_ROWS: usize = 1_000_000;
/// Default `--max-csv-mb`.
pub const MAX_CSV_MIB: u64 = 64;

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_rows: MAX_ROWS,
            max_mib: MAX_CSV_MIB,
        }
    }
}

/// One data row: its 1-based line in the file and its cells.
#[derive(Clone, Debug)]
pub struct Row {
    /// 1-based line number.
    pub line: u64,
    /// Cells, trimmed.
    pub cells: Vec<String>,
}

/// A CSV file's header (if its first row is not numeric) and data rows.
#[derive(Clone, Debug)]
pub struct Table {
    /// The file, for messages.
    pub path: PathBuf,
    /// Header cells, lower-cased, when the first row was a header.
    pub header: Option<Vec<String>>,
    /// Data rows in file order.
    pub rows: Vec<Row>,
}

/// Bytes in MiB with one decimal, for messages.
fn mib(bytes: u64) -> String {
    format!("{:.1}", bytes as f64 / (1u64 << 20) as f64)
}

/// True when `s` parses as a finite-or-not float (so "nan" counts as a number and is
/// rejected later as out of range rather than mistaken for a header).
fn is_number(s: &str) -> bool {
    s.parse::<f64>().is_ok()
}

impl Table {
    /// Reads `path` within `limits`. A first row whose first cell is not a number is taken
    /// as the header. The size is checked before reading and again while reading (a pipe
    /// or a growing file has no size to check first).
    pub fn read(path: &Path, limits: Limits) -> Result<Table, CalError> {
        let read_err = |source| CalError::Read {
            path: path.to_path_buf(),
            source,
        };
        let max_bytes = limits.max_mib.saturating_mul(1 << 20);
        let too_big = |bytes: u64| CalError::OverLimit {
            path: path.to_path_buf(),
            what: format!(
                "{} MiB of CSV, over the {} MiB limit by {} MiB",
                mib(bytes),
                limits.max_mib,
                mib(bytes.saturating_sub(max_bytes))
            ),
            option: CalOption::MaxCsvMb,
        };
        let file = std::fs::File::open(path).map_err(read_err)?;
        let len = file.metadata().map_err(read_err)?.len();
        if len > max_bytes {
            return Err(too_big(len));
        }
        let mut bytes = Vec::new();
        file.take(max_bytes.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(read_err)?;
        if bytes.len() as u64 > max_bytes {
            return Err(too_big(bytes.len() as u64));
        }
        Table::parse(path, &bytes, limits.max_rows)
    }

    /// Parses CSV text already in memory, at most `max_rows` data rows; `path` only names
    /// it in messages.
    pub fn parse(path: &Path, bytes: &[u8], max_rows: usize) -> Result<Table, CalError> {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .from_reader(bytes);
        let mut header = None;
        let mut rows = Vec::new();
        let mut extra = 0usize;
        for record in reader.records() {
            let record = record.map_err(|e| CalError::Csv {
                path: path.to_path_buf(),
                line: e.position().map(|p| p.line()).unwrap_or(0),
                message: e.to_string(),
            })?;
            let line = record.position().map(|p| p.line()).unwrap_or(0);
            let cells: Vec<String> = record.iter().map(str::to_string).collect();
            if cells.iter().all(|c| c.is_empty()) {
                continue;
            }
            let first_row = header.is_none() && rows.is_empty();
            if first_row && !cells.first().is_some_and(|c| is_number(c)) {
                header = Some(cells.iter().map(|c| c.to_lowercase()).collect());
                continue;
            }
            if rows.len() < max_rows {
                rows.push(Row { line, cells });
            } else {
                // Past the limit the rows are only counted, so the refusal can say by how
                // much without holding them.
                extra += 1;
            }
        }
        if extra > 0 {
            return Err(CalError::OverLimit {
                path: path.to_path_buf(),
                what: format!(
                    "{} data rows, over the limit of {max_rows} by {extra}",
                    max_rows + extra
                ),
                option: CalOption::MaxRows,
            });
        }
        Ok(Table {
            path: path.to_path_buf(),
            header,
            rows,
        })
    }

    /// Fails unless there are at least `need` data rows.
    pub fn require_rows(&self, need: usize) -> Result<(), CalError> {
        match self.rows.len() {
            0 => Err(CalError::Empty {
                path: self.path.clone(),
            }),
            n if n < need => Err(CalError::TooFewRows {
                path: self.path.clone(),
                rows: n,
                need,
            }),
            _ => Ok(()),
        }
    }

    /// Header name of column `col` (0-based), if any.
    pub fn header_of(&self, col: usize) -> Option<&str> {
        self.header.as_ref()?.get(col).map(String::as_str)
    }

    /// Number of columns: the header's, else the widest row's.
    pub fn columns(&self) -> usize {
        match &self.header {
            Some(h) => h.len(),
            None => self.rows.iter().map(|r| r.cells.len()).max().unwrap_or(0),
        }
    }

    /// "2 (stress_pa)" style name of column `col` for messages.
    pub fn column_name(&self, col: usize) -> String {
        match self.header_of(col) {
            Some(h) if !h.is_empty() => format!("{} ({h})", col + 1),
            _ => format!("{}", col + 1),
        }
    }

    fn cell<'a>(&self, row: &'a Row, col: usize) -> Result<&'a str, CalError> {
        row.cells
            .get(col)
            .map(String::as_str)
            .ok_or_else(|| CalError::MissingCells {
                path: self.path.clone(),
                line: row.line,
                got: row.cells.len(),
                need: col + 1,
            })
    }

    /// Column `col` as numbers, each checked by `bound`.
    pub fn numbers(&self, col: usize, bound: Bound) -> Result<Vec<f64>, CalError> {
        let mut out = Vec::with_capacity(self.rows.len());
        for row in &self.rows {
            let text = self.cell(row, col)?;
            let value: f64 = text.parse().map_err(|_| CalError::NotNumeric {
                path: self.path.clone(),
                line: row.line,
                column: self.column_name(col),
                text: text.to_string(),
            })?;
            if let Some(need) = bound.violated_by(value) {
                return Err(CalError::OutOfRange {
                    path: self.path.clone(),
                    line: row.line,
                    column: self.column_name(col),
                    value,
                    need,
                });
            }
            out.push(value);
        }
        Ok(out)
    }

    /// Column `col` as text (empty where a row is short).
    pub fn texts(&self, col: usize) -> Vec<String> {
        self.rows
            .iter()
            .map(|r| r.cells.get(col).cloned().unwrap_or_default())
            .collect()
    }

    /// 1-based line of data row `i`.
    pub fn line_of(&self, i: usize) -> u64 {
        self.rows.get(i).map(|r| r.line).unwrap_or(0)
    }
}

/// What a numeric column must satisfy (every value must at least be finite).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// Any finite number.
    Finite,
    /// Zero or more.
    NonNegative,
    /// Above zero.
    Positive,
}

impl Bound {
    fn violated_by(self, v: f64) -> Option<&'static str> {
        if !v.is_finite() {
            return Some("a finite number");
        }
        match self {
            Bound::Finite => None,
            Bound::NonNegative if v < 0.0 => Some("zero or more"),
            Bound::Positive if v <= 0.0 => Some("above zero"),
            _ => None,
        }
    }
}
