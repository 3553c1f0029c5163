//! Files kept across restarts under the data folder (`--data DIR`): uploaded designs,
//! G-code and sliced jobs (`.dlp`) in `DIR/files/`, machine configs by name in
//! `DIR/configs/`. Names are sanitised (letters, digits, `._-`, no folders, no leading
//! dot, at most `MAX_NAME` characters, an extension the folder takes); a file is at most
//! `MAX_FILE` bytes and a folder holds at most its `max_files`. Writes are atomic (a
//! temporary file renamed). This file stops at bytes on disk: what a file means (a job
//! decoded, G-code imported, a config checked) is `files`'.

use super::error::{ApiError, ApiResult};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Largest file kept, bytes (one upload's limit).
pub const MAX_FILE: usize = super::MAX_UPLOAD;
/// Files kept in `files/` (designs, G-code, jobs).
pub const MAX_FILES: usize = 200;
/// Configs kept by name.
pub const MAX_CONFIGS: usize = 100;
/// Longest file name, characters.
pub const MAX_NAME: usize = 96;

/// What a file is, by its extension.
pub fn kind_of(name: &str) -> Option<&'static str> {
    let ext = name.rsplit_once('.')?.1.to_ascii_lowercase();
    Some(match ext.as_str() {
        "dlp" => "job",
        "gcode" | "gco" | "g" => "gcode",
        "png" | "jpg" | "jpeg" | "bmp" | "stl" | "3mf" => "design",
        "toml" => "config",
        _ => return None,
    })
}

/// One file as the Files page lists it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Entry {
    /// Its name.
    pub name: String,
    /// `job`, `gcode`, `design` or `config`.
    pub kind: String,
    /// Size, bytes.
    pub bytes: u64,
    /// Last written, seconds since 1970.
    pub modified_unix_s: f64,
}

/// A folder of kept files.
pub struct Folder {
    dir: PathBuf,
    max_files: usize,
    /// The kinds this folder takes.
    kinds: &'static [&'static str],
    /// What the folder is called in messages ("file", "config").
    what: &'static str,
}

/// The last part of `name` (after any `/` or backslash, as a browser on any system may send it),
/// with characters other than letters, digits and `._-` replaced by `_` and leading dots
/// dropped: a name that cannot leave the folder it is written in. May be empty.
pub fn plain_name(name: &str) -> String {
    let base = name.rsplit(['/', '\\']).next().unwrap_or("");
    let clean: String = base
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    clean.trim_start_matches('.').to_string()
}

/// `name` made safe: its last path part, characters outside letters, digits and `._-`
/// replaced by `_`, leading dots dropped (`plain_name`); refused when nothing is left, it is too long,
/// or its extension is not one `kinds` takes.
pub fn clean_name(name: &str, kinds: &[&str]) -> ApiResult<String> {
    let clean = plain_name(name);
    if clean.is_empty() {
        return Err(ApiError::bad(format!(
            "{name:?}: give the file a name (letters, digits, . _ -)"
        )));
    }
    if clean.chars().count() > MAX_NAME {
        return Err(ApiError::bad(format!(
            "{name:?}: the name is over {MAX_NAME} characters; shorten it"
        )));
    }
    match kind_of(&clean) {
        Some(k) if kinds.contains(&k) => Ok(clean),
        _ => Err(ApiError::bad(format!(
            "{name:?}: not a file this dashboard keeps here ({})",
            kinds
                .iter()
                .map(|k| match *k {
                    "job" => "a job .dlp",
                    "gcode" => "G-code .gcode/.gco/.g",
                    "design" => "a design .png/.jpg/.bmp/.stl/.3mf",
                    _ => "a config .toml",
                })
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

impl Folder {
    /// The jobs, G-code and designs under `data/files`.
    pub fn files(data: &Path) -> ApiResult<Self> {
        Self::open(
            data.join("files"),
            MAX_FILES,
            &["job", "gcode", "design"],
            "file",
        )
    }

    /// The configs by name under `data/configs`.
    pub fn configs(data: &Path) -> ApiResult<Self> {
        Self::open(data.join("configs"), MAX_CONFIGS, &["config"], "config")
    }

    fn open(
        dir: PathBuf,
        max_files: usize,
        kinds: &'static [&'static str],
        what: &'static str,
    ) -> ApiResult<Self> {
        std::fs::create_dir_all(&dir).map_err(|e| {
            ApiError::internal(format!("cannot create the folder {}: {e}", dir.display()))
        })?;
        Ok(Folder {
            dir,
            max_files,
            kinds,
            what,
        })
    }

    /// The folder's files, newest first.
    pub fn list(&self) -> Vec<Entry> {
        let mut out = Vec::new();
        let Ok(rd) = std::fs::read_dir(&self.dir) else {
            return out;
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let Some(kind) = kind_of(&name).filter(|k| self.kinds.contains(k)) else {
                continue;
            };
            let Ok(meta) = e.metadata() else { continue };
            if !meta.is_file() {
                continue;
            }
            let modified_unix_s = meta
                .modified()
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0.0, |d| d.as_secs_f64());
            out.push(Entry {
                name,
                kind: kind.into(),
                bytes: meta.len(),
                modified_unix_s,
            });
        }
        out.sort_by(|a, b| {
            b.modified_unix_s
                .total_cmp(&a.modified_unix_s)
                .then(a.name.cmp(&b.name))
        });
        out
    }

    /// The path of an existing file named exactly `name` (a name that is not already
    /// clean names nothing here).
    fn existing(&self, name: &str) -> ApiResult<PathBuf> {
        let clean = clean_name(name, self.kinds)
            .map_err(|_| ApiError::missing(format!("no {} named {name:?}", self.what)))?;
        let path = self.dir.join(&clean);
        if clean != name || !path.is_file() {
            return Err(ApiError::missing(format!(
                "no {} named {name:?}",
                self.what
            )));
        }
        Ok(path)
    }

    /// A file's bytes.
    pub fn read(&self, name: &str) -> ApiResult<Vec<u8>> {
        let path = self.existing(name)?;
        std::fs::read(&path).map_err(|e| ApiError::internal(format!("cannot read {name}: {e}")))
    }

    /// Keeps `bytes` as `name` (cleaned; an existing file of that name is replaced);
    /// returns the name it has.
    pub fn write(&self, name: &str, bytes: &[u8]) -> ApiResult<String> {
        let clean = clean_name(name, self.kinds)?;
        if bytes.len() > MAX_FILE {
            return Err(ApiError::TooLarge(format!(
                "{clean}: {} MiB, over the {} MiB a kept file may have",
                bytes.len() >> 20,
                MAX_FILE >> 20
            )));
        }
        let path = self.dir.join(&clean);
        if !path.exists() && self.list().len() >= self.max_files {
            return Err(ApiError::conflict(format!(
                "{clean}: the dashboard keeps at most {} {}s; delete some first",
                self.max_files, self.what
            )));
        }
        let tmp = self.dir.join(format!(".{clean}.part"));
        std::fs::write(&tmp, bytes)
            .and_then(|_| std::fs::rename(&tmp, &path))
            .map_err(|e| {
                let _ = std::fs::remove_file(&tmp);
                ApiError::internal(format!("cannot keep {clean}: {e}"))
            })?;
        Ok(clean)
    }

    /// Deletes a file.
    pub fn delete(&self, name: &str) -> ApiResult<()> {
        let path = self.existing(name)?;
        std::fs::remove_file(&path)
            .map_err(|e| ApiError::internal(format!("cannot delete {name}: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_cleaned_and_cannot_leave_the_folder() {
        let dir = tempfile::tempdir().expect("folder");
        let f = Folder::files(dir.path()).expect("opens");
        assert_eq!(f.write("../../etc/x.dlp", b"a").unwrap(), "x.dlp");
        assert_eq!(
            f.write("my part (2).gcode", b"b").unwrap(),
            "my_part__2_.gcode"
        );
        assert_eq!(f.write("..hidden.stl", b"c").unwrap(), "hidden.stl");
        assert!(dir.path().join("files/x.dlp").is_file());
        for bad in [
            "notes.txt",
            "",
            "/",
            "x.toml",
            &format!("{}.dlp", "a".repeat(97)),
        ] {
            let e = f.write(bad, b"d").unwrap_err();
            assert_eq!(e.status(), axum::http::StatusCode::BAD_REQUEST, "{bad}");
        }
        // Reading goes by the exact clean name only.
        assert_eq!(f.read("x.dlp").unwrap(), b"a");
        for bad in ["../files/x.dlp", "..%2Fx.dlp", "X.DLP", "x.dlp/"] {
            assert_eq!(
                f.read(bad).unwrap_err().status(),
                axum::http::StatusCode::NOT_FOUND,
                "{bad}"
            );
        }
        let names: Vec<String> = f.list().into_iter().map(|e| e.name).collect();
        assert_eq!(names.len(), 3, "{names:?}");
        f.delete("x.dlp").unwrap();
        assert!(f.read("x.dlp").is_err());
        assert_eq!(f.list().len(), 2);
    }

    #[test]
    fn the_count_limit_refuses_a_new_file_but_replaces_an_old_one() {
        let dir = tempfile::tempdir().expect("folder");
        let c = Folder::configs(dir.path()).expect("opens");
        for i in 0..MAX_CONFIGS {
            c.write(&format!("c{i}.toml"), b"x").unwrap();
        }
        let e = c.write("one-more.toml", b"x").unwrap_err();
        assert!(
            e.message().contains("at most 100 configs"),
            "{}",
            e.message()
        );
        c.write("c0.toml", b"y").expect("replacing is not adding");
        assert_eq!(c.read("c0.toml").unwrap(), b"y");
    }
}
