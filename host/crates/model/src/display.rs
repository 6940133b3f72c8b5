//! Numbers as a person reads them in a message.

use std::fmt;

/// An `f64` in its shortest exact form: as typed (`2000`, `0.25`) while that is short,
/// in exponent form (`1e308`, `5e-324`) when the plain digits would run long. Rust's
/// `{}` prints `1e308` as 309 digits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shortest(pub f64);

impl fmt::Display for Shortest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let plain = self.0.to_string();
        let exponent = format!("{:e}", self.0);
        // A few characters more for the plain form buy not having to read an exponent.
        if plain.len() <= exponent.len() + 4 {
            f.write_str(&plain)
        } else {
            f.write_str(&exponent)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Shortest;

    #[test]
    fn plain_while_short_exponent_when_long() {
        let shown = |v: f64| Shortest(v).to_string();
        assert_eq!(shown(2000.0), "2000");
        assert_eq!(shown(0.25), "0.25");
        assert_eq!(shown(-20.0), "-20");
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-1e308), "-1e308");
        assert_eq!(shown(5e-324), "5e-324");
        assert_eq!(shown(1e-300), "1e-300");
        assert_eq!(shown(123456.789), "123456.789");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(shown(f64::INFINITY), "inf");
        for v in [1e308, 5e-324, 0.1, 1.0 / 3.0, 6.02e23] {
            assert_eq!(shown(v).parse::<f64>().unwrap(), v, "exact");
        }
    }
}
