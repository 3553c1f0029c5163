//! The OctoPrint API's commands, as slicers send them after an upload and from their
//! monitor (Cura's OctoPrint plugin): a job's pause, resume, cancel and start
//! (`POST /api/job`), selecting and printing a kept file (`POST /api/files/local/NAME`),
//! and the G-code its monitor's buttons send (`POST /api/printer/command`: jog as `G91`
//! then `G0`/`G1`, home as `G28`). Nothing else is run from there: a paste printer's
//! valves and extrusion belong to the job, so any other line is refused, naming it. Each
//! answers 204 once the board has done the order, or a plain-text refusal. These orders
//! go to board 0 (the one printer an OctoPrint instance has) and, like an upload's
//! `print`, do not wait for the tab that commands the board on the dashboard. This file
//! stops at turning requests into the boards' orders.

use super::boards::{Board, WorkerOrder};
use super::design::SliceForm;
use super::error::ApiError;
use super::jobs::JobEntry;
use super::octoprint_common::{board_for, job_flags, OpResult, Plain};
use super::reply::blocking;
use super::state::AppState;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use dollop::Axis;
use serde::Deserialize;
use std::sync::Arc;

type St = State<Arc<AppState>>;

/// Most G-code lines one `printer/command` request may carry (Cura sends three for a jog).
pub const MAX_LINES: usize = 64;

/// A command body: `{"command": ..., ...}`.
#[derive(Deserialize)]
struct Command {
    command: String,
    #[serde(default)]
    action: Option<String>,
    #[serde(default)]
    print: bool,
}

fn parse<T: for<'de> Deserialize<'de>>(body: &[u8], what: &str) -> OpResult<T> {
    serde_json::from_slice(body).map_err(|e| {
        Plain(ApiError::bad(format!(
            "the {what} request is not the JSON OctoPrint's API takes ({e})"
        )))
    })
}

/// Queues `job` on `board` (it starts when the board is free); the console says so.
pub async fn send(st: &AppState, board: &Board, job: Arc<JobEntry>, kept: &str) -> OpResult<()> {
    let name = board.view.borrow().name.clone();
    match board.order(WorkerOrder::Send(job)).await {
        Ok(m) => {
            st.console.info(&name, format!("send: {m}"));
            Ok(())
        }
        Err(m) => {
            st.console.error(&name, format!("send refused: {m}"));
            Err(Plain(ApiError::conflict(format!(
                "{kept} is kept (print it from the Files page) but the board did not take it: {m}"
            ))))
        }
    }
}

fn first_board(st: &AppState) -> OpResult<Arc<Board>> {
    board_for(st, "")
}

/// Carries out one order on `board`, saying what happened on the console under `what`.
async fn carry_out(st: &AppState, board: &Board, what: &str, order: WorkerOrder) -> OpResult<()> {
    let name = board.view.borrow().name.clone();
    let done = match order {
        WorkerOrder::Abort => board.abort().await,
        o => board.order(o).await,
    };
    match done {
        Ok(m) => {
            st.console
                .info(&name, format!("{what} (from a slicer): {m}"));
            Ok(())
        }
        Err(m) => {
            st.console
                .error(&name, format!("{what} (from a slicer) refused: {m}"));
            Err(Plain(ApiError::conflict(m)))
        }
    }
}

/// `POST /api/job`: `start`, `cancel`, `pause` with `action` `pause`, `resume` or
/// `toggle` (OctoPrint's default).
pub async fn job(State(st): St, body: Bytes) -> OpResult<StatusCode> {
    let c: Command = parse(&body, "job")?;
    let board = first_board(&st)?;
    let (printing, paused) = job_flags(&board.view.borrow());
    let order = match (c.command.as_str(), c.action.as_deref()) {
        ("cancel", _) => (WorkerOrder::Abort, "cancel"),
        ("pause", Some("pause")) => (WorkerOrder::Pause, "pause"),
        ("pause", Some("resume")) => (WorkerOrder::Resume, "resume"),
        ("pause", None | Some("toggle")) if paused => (WorkerOrder::Resume, "resume"),
        ("pause", None | Some("toggle")) => (WorkerOrder::Pause, "pause"),
        ("pause", Some(other)) => {
            return Err(Plain(ApiError::bad(format!(
                "pause's action {other:?}: send pause, resume or toggle"
            ))))
        }
        ("start", _) if printing => {
            return Err(Plain(ApiError::conflict(
                "a job is already running on the board: pause or cancel it first",
            )))
        }
        ("start", _) => (WorkerOrder::StartNext, "start"),
        ("restart", _) => {
            return Err(Plain(ApiError::conflict(
                "a paused job cannot be restarted from its start: cancel it, clear the plate and print the file again",
            )))
        }
        (other, _) => {
            return Err(Plain(ApiError::bad(format!(
                "no job command {other:?}: send start, pause or cancel"
            ))))
        }
    };
    carry_out(&st, &board, order.1, order.0).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// `POST /api/files/local/NAME`: `select` (every kept file is ready to print, so alone it
/// changes nothing) with `print: true` to queue it on board 0.
pub async fn file_command(
    State(st): St,
    Path(name): Path<String>,
    body: Bytes,
) -> OpResult<StatusCode> {
    let c: Command = parse(&body, "file command")?;
    if c.command != "select" {
        return Err(Plain(ApiError::bad(format!(
            "no file command {:?} here: send select (with print true to print it)",
            c.command
        ))));
    }
    let bytes = st.files.read(&name)?;
    if !c.print {
        return Ok(StatusCode::NO_CONTENT);
    }
    let board = first_board(&st)?;
    // Imported again for the board it prints on.
    let config = board.config.get().map(|k| k.text);
    let st2 = st.clone();
    let name2 = name.clone();
    let job = blocking(move || {
        super::files::job_from_file(&st2, &name2, bytes, config, &SliceForm::default())
    })
    .await?;
    send(&st, &board, job, &name).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// One order a monitor's G-code line asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Line {
    /// `G90` / `G91`: absolute or relative moves from here on.
    Relative(bool),
    /// A relative move, mm per axis (zero axes are not moved).
    Jog([f64; 3]),
    /// `G28`, whatever axes it names: the board homes all of them.
    Home,
}

/// Reads one G-code line of a monitor's; `relative` is the mode the lines before set.
fn read_line(text: &str, relative: bool) -> Result<Option<Line>, String> {
    let code = text.split(';').next().unwrap_or("").trim();
    if code.is_empty() {
        return Ok(None);
    }
    let mut words = code.split_whitespace();
    let head = words.next().unwrap_or("").to_ascii_uppercase();
    match head.as_str() {
        "G90" => Ok(Some(Line::Relative(false))),
        "G91" => Ok(Some(Line::Relative(true))),
        "G28" => Ok(Some(Line::Home)),
        "G0" | "G1" | "G00" | "G01" => {
            let mut d = [0.0; 3];
            for w in words {
                let (letter, value) = w.split_at(w.chars().next().map_or(0, char::len_utf8));
                let axis = match letter.to_ascii_uppercase().as_str() {
                    "X" => 0,
                    "Y" => 1,
                    "Z" => 2,
                    // The board jogs at its own speed.
                    "F" => continue,
                    _ => return Err(format!("{code:?}: only X, Y, Z and F are taken in a jog")),
                };
                d[axis] = value
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("{code:?}: {w:?} is not a number of mm"))?;
            }
            if !relative && d != [0.0; 3] {
                return Err(format!(
                    "{code:?}: absolute moves are not taken from a slicer's monitor; jog with G91 first"
                ));
            }
            Ok(Some(Line::Jog(d)))
        }
        _ => Err(format!(
            "{code:?}: a slicer's monitor may jog (G91 then G0/G1) and home (G28) here, nothing else; the valves and extrusion are the job's"
        )),
    }
}

/// What a batch of monitor lines asks the board to do, in order.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    /// Move one axis by this many mm.
    Jog(Axis, f64),
    /// Home every axis.
    Home,
}

/// The steps a batch of monitor lines asks for, every line checked before any runs.
fn read_lines(lines: &[String]) -> Result<Vec<Step>, String> {
    if lines.len() > MAX_LINES {
        return Err(format!(
            "{} lines in one request; at most {MAX_LINES} are taken",
            lines.len()
        ));
    }
    let (mut relative, mut orders) = (false, Vec::new());
    for l in lines {
        match read_line(l, relative)? {
            Some(Line::Relative(r)) => relative = r,
            Some(Line::Home) => orders.push(Step::Home),
            Some(Line::Jog(d)) => {
                for (axis, mm) in [Axis::X, Axis::Y, Axis::Z].into_iter().zip(d) {
                    if mm != 0.0 {
                        orders.push(Step::Jog(axis, mm));
                    }
                }
            }
            None => {}
        }
    }
    Ok(orders)
}

/// `POST /api/printer/command`: `{"commands": [..]}` or `{"command": ".."}`.
pub async fn printer_command(State(st): St, body: Bytes) -> OpResult<StatusCode> {
    #[derive(Deserialize)]
    struct Lines {
        #[serde(default)]
        commands: Vec<String>,
        #[serde(default)]
        command: Option<String>,
    }
    let l: Lines = parse(&body, "printer command")?;
    let lines: Vec<String> = l.commands.into_iter().chain(l.command).collect();
    let steps = read_lines(&lines).map_err(|m| Plain(ApiError::bad(m)))?;
    let board = first_board(&st)?;
    // The server's --config for a board that has none yet, as the dashboard's own jog
    // falls back to.
    let fallback = || st.cli_config.clone().map(Box::new);
    for step in steps {
        match step {
            Step::Home => {
                carry_out(&st, &board, "home", WorkerOrder::Home(fallback())).await?;
                homed(&board).await?;
            }
            Step::Jog(a, mm) => {
                carry_out(&st, &board, "jog", WorkerOrder::Jog(a, mm, fallback())).await?
            }
        }
    }
    Ok(StatusCode::NO_CONTENT)
}

/// Longest a `G28` waits for the board to finish homing, s.
pub const HOMING_WAIT_S: u64 = 300;

/// Waits until the board has homed (the home order returns once homing starts), so that
/// the lines after a `G28` find it homed and the slicer hears of a failed homing. The
/// worker publishes a view after every status poll (at least every 0.1 s); only views
/// published after the order's answer count, so a machine homed before the `G28` is not
/// taken as done before its status shows the new homing.
async fn homed(board: &Board) -> OpResult<()> {
    let mut view = board.view.clone();
    let after = view.borrow_and_update().seq;
    let wait = async {
        loop {
            if view.changed().await.is_err() {
                return Err(ApiError::internal(
                    "the board's worker stopped during homing; restart dollop serve",
                ));
            }
            let v = view.borrow_and_update();
            if v.seq <= after {
                continue;
            }
            if let Some(f) = &v.fault {
                return Err(ApiError::conflict(format!("homing failed: {f}")));
            }
            if v.homed && v.mode != Some(dollop::wire::Mode::Homing) {
                return Ok(());
            }
        }
    };
    match tokio::time::timeout(std::time::Duration::from_secs(HOMING_WAIT_S), wait).await {
        Ok(r) => r.map_err(Plain),
        Err(_) => Err(Plain(ApiError::conflict(format!(
            "the board did not finish homing within {HOMING_WAIT_S} s"
        )))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(l: &[&str]) -> Result<Vec<Step>, String> {
        read_lines(&l.iter().map(|s| s.to_string()).collect::<Vec<_>>())
    }

    fn shape(o: &[Step]) -> Vec<String> {
        o.iter()
            .map(|o| match o {
                Step::Jog(a, mm) => format!("jog {a:?} {mm}"),
                Step::Home => "home".into(),
            })
            .collect()
    }

    #[test]
    fn a_monitors_jog_and_home_become_board_orders() {
        // What Cura's OctoPrintOutputController sends for a jog, and its home button.
        let o = lines(&["G91", "G0 X10 Y0 Z0 F6000", "G90"]).unwrap();
        assert_eq!(shape(&o), ["jog X 10"]);
        let o = lines(&["G91", "G1 x-1.5 Z2 ; up", "G28 X Y"]).unwrap();
        assert_eq!(shape(&o), ["jog X -1.5", "jog Z 2", "home"]);
        assert!(lines(&["", "; nothing"]).unwrap().is_empty());
    }

    #[test]
    fn anything_else_is_refused_naming_the_line() {
        for (l, says) in [
            (vec!["G0 X10"], "absolute moves"),
            (vec!["G91", "G0 XNaN"], "not a number"),
            (vec!["G91", "G1 E5"], "only X, Y, Z"),
            (vec!["M42 P1 S255"], "M42 P1 S255"),
            (vec!["T1"], "nothing else"),
        ] {
            let Err(e) = lines(&l) else {
                panic!("{l:?} was taken")
            };
            assert!(e.contains(says), "{l:?}: {e}");
        }
        let many = vec!["G90"; MAX_LINES + 1];
        assert!(lines(&many).is_err_and(|e| e.contains("at most")));
    }
}
