//! The machine config a board has, as this dashboard last loaded it there (a job's as the
//! job started, or the page's or `--config` before a manual order): kept beside the board
//! so that G-code headed for that board (an upload from a slicer) is imported for that
//! machine, its section, tools and limits, rather than the first config offered. Stops
//! there: loading is the worker's (`boards`), importing is `files`'. A config the board
//! had before this dashboard started is not known here (the board reports only its hash).

use super::lock::lock;
use dollop::config::Config;
use std::sync::Mutex;

/// A config and its TOML text.
#[derive(Clone, Debug)]
pub struct Known {
    /// The config.
    pub config: Config,
    /// Its text: the one it was given as, else written from the config.
    pub text: String,
}

/// The config last loaded on one board (none yet).
#[derive(Default)]
pub struct LoadedConfig(Mutex<Option<Known>>);

impl LoadedConfig {
    /// The board now has `config`; `text` is its TOML when known. A config that cannot be
    /// written as TOML (it always can: plain numbers and tables) leaves the slot empty, so
    /// the default is used rather than a text that would not read back.
    pub fn set(&self, config: &Config, text: Option<&str>) {
        let text = match text {
            Some(t) => Some(t.to_string()),
            None => toml::to_string(config).ok(),
        };
        *lock(&self.0) = text.map(|text| Known {
            config: config.clone(),
            text,
        });
    }

    /// The config last loaded, if any.
    pub fn get(&self) -> Option<Known> {
        lock(&self.0).clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_config_without_its_text_is_written_so_that_it_reads_back_the_same() {
        let text = crate::serve::design::BUNDLED[1].1;
        let config = crate::serve::design::check(text).expect("config").config;
        let slot = LoadedConfig::default();
        assert!(slot.get().is_none());
        slot.set(&config, None);
        let back = crate::serve::design::check(&slot.get().expect("set").text)
            .expect("reads back")
            .config;
        assert_eq!(
            dollop::job::config_hash(&back),
            dollop::job::config_hash(&config)
        );
        slot.set(&config, Some(text));
        assert_eq!(slot.get().expect("set").text, text);
    }
}
