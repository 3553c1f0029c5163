//! Number formatting shared by the reports and the TOML fragments: significant digits,
//! estimates with intervals, and TOML-safe floats. Layout of each report is its module's.

use super::fit::Estimate;

/// `v` with `sig` significant digits, plain notation between 1e-4 and 1e7.
pub fn sig(v: f64, sig: usize) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-4..7).contains(&mag) {
        return format!("{:.*e}", sig.saturating_sub(1), v);
    }
    let decimals = (sig as i32 - 1 - mag).max(0) as usize;
    format!("{v:.decimals$}")
}

/// Up to 4 significant digits without trailing zeros: for values that came from the
/// config's f32 fields (0.8 rather than 0.800000011920929).
pub fn short(v: f64) -> String {
    let s = sig(v, 4);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A float TOML reads back as a float (always a decimal point or an exponent), rounded to
/// `digits` significant digits: the config stores f32, so 6 is plenty.
pub fn toml_float(v: f64, digits: usize) -> String {
    let s = sig(v, digits);
    if s.contains(['e', 'E']) || !v.is_finite() {
        return s;
    }
    if !s.contains('.') {
        return format!("{s}.0");
    }
    let trimmed = s.trim_end_matches('0');
    if trimmed.ends_with('.') {
        format!("{trimmed}0")
    } else {
        trimmed.to_string()
    }
}

/// "61.2 [58.9, 63.6] Pa s^n".
pub fn estimate(e: &Estimate) -> String {
    let unit = if e.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", e.unit)
    };
    format!(
        "{} = {} [{}, {}]{unit}",
        e.name,
        sig(e.value, 4),
        sig(e.lo, 3),
        sig(e.hi, 3)
    )
}

/// RMS of log residuals in words: a relative error while it is small, the plain number
/// once the log scale no longer reads as a percentage.
pub fn log_rms(rms: f64) -> String {
    if rms < 0.2 {
        format!("RMS {:.2} % (relative)", 100.0 * rms)
    } else {
        format!("RMS log residual {rms:.3}")
    }
}

/// A TOML basic string literal with the characters TOML requires escaped.
pub fn toml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 || c == '\u{7f}' => {
                out.push_str(&format!("\\u{:04X}", c as u32))
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(sig(61.234, 4), "61.23");
        assert_eq!(sig(0.59812, 3), "0.598");
        assert_eq!(sig(12345.6, 3), "12346");
        assert_eq!(sig(1.5e-6, 3), "1.50e-6");
        assert_eq!(toml_float(60.0, 6), "60.0");
        assert_eq!(short(0.800000011920929), "0.8");
        assert_eq!(short(2.4000000953674316), "2.4");
        assert_eq!(toml_float(0.59812, 3), "0.598");
        assert_eq!(toml_float(12345678.0, 3), "1.23e7");
        assert_eq!(toml_string("a \"b\"\n"), "\"a \\\"b\\\"\\u000A\"");
    }
}
