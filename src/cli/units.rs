//! Lengths with units on the command line: `2.5mm`, `0.0025 m`, `1e-3m`.
//!
//! In: text. Out: metres (finite, > 0), or an error saying what is accepted.

/// Parses a length with a unit (`mm` or `m`) into metres.
pub fn parse_length(text: &str) -> Result<f64, String> {
    let t = text.trim();
    let (number, factor) = if let Some(n) = t.strip_suffix("mm") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 1.0)
    } else {
        return Err(format!("`{text}` needs a unit: mm or m (e.g. 2.5mm)"));
    };
    let value: f64 = number.trim().parse().map_err(|_| format!("`{text}` is not a number followed by mm or m"))?;
    if !(value.is_finite() && value > 0.0) {
        return Err(format!("`{text}` must be a finite length > 0"));
    }
    Ok(value * factor)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_parse_with_units() {
        assert_eq!(parse_length("2.5mm"), Ok(2.5e-3));
        assert_eq!(parse_length(" 0.01 m "), Ok(0.01));
        assert_eq!(parse_length("1e-3m"), Ok(1e-3));
        for bad in ["2.5", "mm", "-1mm", "0mm", "infmm", "2.5 cm", "2,5mm"] {
            assert!(parse_length(bad).is_err(), "{bad:?} must be rejected");
        }
    }
}
