//! The console and the live plots: a bounded log of the server's events (orders accepted
//! or refused, uploads, files) and the boards' (what each board is doing, job start and
//! end, faults, messages), and per board a bounded trend of line pressures, flow and head
//! speed sampled once a second while it is connected. A watcher task reads the boards'
//! status to fill both; the status stream carries only the newest sample and the log's
//! sequence number (the page fetches the rest), so its size stays bounded. This file stops
//! at keeping them: the routes serve them, the page draws them.

use super::boards::Board;
use super::lock::lock;
use super::view::View;
use serde::Serialize;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Lines the console keeps (oldest dropped first).
pub const LOG_LINES: usize = 300;
/// Trend samples kept per board: one a second, so the last five minutes.
pub const TREND_SAMPLES: usize = 300;

/// One console line.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Line {
    /// Its number (rising).
    pub seq: u64,
    /// When, ms since 1970.
    pub unix_ms: f64,
    /// `server`, or the board's name.
    pub source: String,
    /// `info` or `error`.
    pub level: &'static str,
    /// What happened, in plain words.
    pub text: String,
}

/// One trend sample.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Sample {
    /// When, ms since 1970.
    pub unix_ms: f64,
    /// Head speed, mm/s.
    pub speed: f64,
    /// Flow, mm³/s.
    pub flow: f64,
    /// Each inlet's line pressure, kPa (empty on a board without a plant).
    pub line_kpa: Vec<f64>,
}

/// The console and the boards' trends.
pub struct Console {
    lines: Mutex<VecDeque<Line>>,
    seq: AtomicU64,
    trends: Mutex<Vec<VecDeque<Sample>>>,
}

fn now_ms() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

impl Console {
    /// Empty, with a trend per board.
    pub fn new(boards: usize) -> Self {
        Console {
            lines: Mutex::new(VecDeque::new()),
            seq: AtomicU64::new(0),
            trends: Mutex::new(vec![VecDeque::new(); boards]),
        }
    }

    fn push(&self, source: &str, level: &'static str, text: String) {
        let seq = self.seq.fetch_add(1, Ordering::Relaxed) + 1;
        let mut l = lock(&self.lines);
        l.push_back(Line {
            seq,
            unix_ms: now_ms(),
            source: source.into(),
            level,
            text,
        });
        while l.len() > LOG_LINES {
            l.pop_front();
        }
    }

    /// Logs an event.
    pub fn info(&self, source: &str, text: impl Into<String>) {
        self.push(source, "info", text.into());
    }

    /// Logs a refusal or a fault.
    pub fn error(&self, source: &str, text: impl Into<String>) {
        self.push(source, "error", text.into());
    }

    /// The newest line's number (0: none yet).
    pub fn seq(&self) -> u64 {
        self.seq.load(Ordering::Relaxed)
    }

    /// The lines, newest first.
    pub fn lines(&self) -> Vec<Line> {
        lock(&self.lines).iter().rev().cloned().collect()
    }

    /// Adds a board's sample.
    pub fn sample(&self, board: usize, s: Sample) {
        let mut t = lock(&self.trends);
        if let Some(q) = t.get_mut(board) {
            q.push_back(s);
            while q.len() > TREND_SAMPLES {
                q.pop_front();
            }
        }
    }

    /// A board's trend, oldest first.
    pub fn trend(&self, board: usize) -> Vec<Sample> {
        lock(&self.trends)
            .get(board)
            .map(|q| q.iter().cloned().collect())
            .unwrap_or_default()
    }

    /// A board's newest sample.
    pub fn latest(&self, board: usize) -> Option<Sample> {
        lock(&self.trends)
            .get(board)
            .and_then(|q| q.back().cloned())
    }
}

/// What changed between two views of a board worth a console line.
pub fn changes(before: &View, now: &View) -> Vec<(&'static str, String)> {
    let mut out = Vec::new();
    if now.connected != before.connected {
        out.push((
            "info",
            if now.connected {
                "connected".to_string()
            } else {
                "not connected".to_string()
            },
        ));
    }
    if now.activity != before.activity && !now.activity.is_empty() {
        out.push(("info", now.activity.clone()));
    }
    if now.fault != before.fault {
        if let Some(f) = &now.fault {
            out.push(("error", format!("fault: {f}")));
        }
    }
    if now.message != before.message {
        if let Some(m) = &now.message {
            out.push(("info", m.clone()));
        }
    }
    out
}

/// Watches every board's status: console lines on changes (ten times a second) and a
/// trend sample a second while connected. Runs until the server stops.
pub fn watch(boards: Vec<Arc<Board>>, console: Arc<Console>) {
    tokio::spawn(async move {
        let mut before: Vec<View> = boards.iter().map(|b| b.view.borrow().clone()).collect();
        let mut tick = 0u64;
        loop {
            tokio::time::sleep(Duration::from_millis(100)).await;
            tick += 1;
            for (i, b) in boards.iter().enumerate() {
                let now = b.view.borrow().clone();
                for (level, text) in changes(&before[i], &now) {
                    if level == "error" {
                        console.error(&now.name, text);
                    } else {
                        console.info(&now.name, text);
                    }
                }
                if tick.is_multiple_of(10) && now.connected {
                    console.sample(
                        i,
                        Sample {
                            unix_ms: now_ms(),
                            speed: now.speed,
                            flow: now.flow,
                            line_kpa: now.line_kpa.clone(),
                        },
                    );
                }
                before[i] = now;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_and_the_trends_stay_bounded_newest_first() {
        let c = Console::new(2);
        for i in 0..LOG_LINES + 7 {
            c.info("server", format!("line {i}"));
        }
        let l = c.lines();
        assert_eq!(l.len(), LOG_LINES);
        assert_eq!(l[0].text, format!("line {}", LOG_LINES + 6));
        assert_eq!(c.seq(), (LOG_LINES + 7) as u64);
        for i in 0..TREND_SAMPLES + 3 {
            c.sample(
                1,
                Sample {
                    unix_ms: i as f64,
                    speed: 1.0,
                    flow: 2.0,
                    line_kpa: vec![3.0],
                },
            );
        }
        c.sample(
            5,
            Sample {
                unix_ms: 0.0,
                speed: 0.0,
                flow: 0.0,
                line_kpa: vec![],
            },
        );
        let t = c.trend(1);
        assert_eq!(t.len(), TREND_SAMPLES);
        assert_eq!(t[0].unix_ms, 3.0);
        assert_eq!(
            c.latest(1).map(|s| s.unix_ms),
            Some((TREND_SAMPLES + 2) as f64)
        );
        assert!(c.trend(0).is_empty());
    }

    #[test]
    fn a_fault_and_a_new_activity_are_logged_once() {
        let a = View {
            activity: "idle".into(),
            connected: true,
            ..Default::default()
        };
        let mut b = a.clone();
        b.activity = "printing logo.png".into();
        b.fault = Some("the line pressure is over its limit".into());
        let c = changes(&a, &b);
        assert_eq!(c.len(), 2, "{c:?}");
        assert_eq!(c[1].0, "error");
        assert!(changes(&b, &b).is_empty());
    }
}
