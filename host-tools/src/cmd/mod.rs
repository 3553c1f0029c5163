//! One module per `dollop` subcommand (or family of them).

pub mod bench;
pub mod calibrate;
pub mod config;
pub mod demo;
pub mod inspect;
pub mod link;
pub mod simulate;
pub mod slice;

/// An error as the command line prints it: one line, the context chain joined by ": "
/// (what `{:#}` prints), with the libraries' errors naming options by their flags (the
/// slicer's options and limits, the link's port).
pub fn one_line(e: &anyhow::Error) -> String {
    e.chain()
        .map(|c| {
            if let Some(s) = c.downcast_ref::<crate::slicer::SliceError>() {
                slice::in_flags(s)
            } else if let Some(l) = c.downcast_ref::<crate::link::LinkError>() {
                l.message(Some("--port PATH"))
            } else {
                c.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join(": ")
}

#[cfg(test)]
mod tests {
    use super::one_line;
    use crate::slicer::{MarkerError, SliceError, SliceLimit, SliceOption};

    #[test]
    fn slicer_errors_say_flags_here_and_plain_words_in_the_library() {
        let e = SliceError::OverLimit {
            what: "a.stl: runs in the first 1 of 17 layers: 12 exceeds the limit of 3 by 9".into(),
            limit: SliceLimit::Segments,
            or: Some(SliceOption::Layers),
        };
        assert!(!e.to_string().contains("--"), "{e}");
        assert_eq!(
            one_line(&anyhow::Error::from(e).context("slicing")),
            "slicing: a.stl: runs in the first 1 of 17 layers: 12 exceeds the limit of 3 by 9 \
             (--max-segments (or --layers) raises it)"
        );
        let e = SliceError::Markers(MarkerError::Layers);
        assert!(!e.to_string().contains("--"), "{e}");
        assert!(one_line(&e.into()).starts_with("--markers: corner markers are for single-layer"));
        let e = crate::link::LinkError::SeveralBoards {
            found: vec!["/dev/ttyACM0".into(), "/dev/ttyACM1".into()],
        };
        assert!(!e.to_string().contains("--"), "{e}");
        assert_eq!(
            one_line(&e.into()),
            "several dollop boards found (/dev/ttyACM0, /dev/ttyACM1); choose one with --port PATH"
        );
    }
}
