//! Logging shim: maps the core's log macros to `defmt` on the chip (feature `defmt`)
//! and to nothing on the host, so host tests link without a defmt global logger.
#![allow(unused_macros, unused_imports)]

#[cfg(feature = "defmt")]
macro_rules! log_warn {
    ($($arg:tt)*) => { defmt::warn!($($arg)*) };
}
#[cfg(not(feature = "defmt"))]
macro_rules! log_warn {
    ($($arg:tt)*) => {{}};
}
pub(crate) use log_warn;
