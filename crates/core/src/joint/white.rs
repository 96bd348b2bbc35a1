//! The Lab white Y_w (docs/filter.md §1): fixed, or `auto` from the dump.
//!
//! The paper's σ_color = 100 assumes radiance 1 is white, so the same scene
//! at another exposure gives other decisions. `auto` makes the white travel
//! with the exposure: Y_w is chosen so that the median luminance of the
//! dump's valid samples with positive luminance sits at mid-grey, L* = 50
//! (Y / Y_w = ((50 + 16) / 116)³ ≈ 0.1842, photography's 18% grey). The
//! median ignores fireflies and small lights whatever their radiance, and
//! scaling every radiance by c scales it by c (up to f32 rounding).

use std::str::FromStr;

use crate::dump::{Header, Record, Validity};
use crate::joint::lab::luminance;
use crate::quantile::{exact, rank};

/// Y / Y_w at L* = 50.
pub const MID_GREY: f64 = 0.184_186_2;

/// A fixed white luminance or `auto`. In JSON a number or `"auto"`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum White {
    Fixed(f64),
    Auto,
}

impl FromStr for White {
    type Err = String;
    fn from_str(s: &str) -> Result<White, String> {
        if s == "auto" {
            return Ok(White::Auto);
        }
        match s.parse::<f64>() {
            Ok(v) if v > 0.0 && v.is_finite() => Ok(White::Fixed(v)),
            _ => Err(format!("expected `auto` or a positive number, got {s:?}")),
        }
    }
}

impl std::fmt::Display for White {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            White::Fixed(v) => write!(f, "{v}"),
            White::Auto => write!(f, "auto"),
        }
    }
}

impl serde::Serialize for White {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            White::Fixed(v) => s.serialize_f64(*v),
            White::Auto => s.serialize_str("auto"),
        }
    }
}

impl<'de> serde::Deserialize<'de> for White {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<White, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Repr {
            Number(f64),
            Text(String),
        }
        let text = match Repr::deserialize(d)? {
            Repr::Number(v) => v.to_string(),
            Repr::Text(t) => t,
        };
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// The median luminance of the valid samples with Y > 0, over MID_GREY
/// (docs/filter.md F3).
pub fn auto_white(records: &[Record], h: &Header) -> Option<f64> {
    let lum = |r: &Record| {
        let y = luminance([r.r as f64, r.g as f64, r.b as f64]) as f32;
        (r.validity(h) == Validity::Valid && y > 0.0 && y.is_finite()).then_some(y)
    };
    let median = exact(records, lum, |n| vec![rank(0.5, n)])?[0] as f64;
    let w = median / MID_GREY;
    (w > 0.0 && w.is_finite()).then_some(w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::joint::lab::rgb_to_lab;

    #[test]
    fn mid_grey_is_l_star_50() {
        let l = rgb_to_lab([MID_GREY; 3], 1.0)[0];
        assert!((l - 50.0).abs() < 1e-4, "{l}");
    }

    #[test]
    fn parses_auto_and_positive_numbers() {
        assert_eq!("auto".parse::<White>(), Ok(White::Auto));
        assert_eq!("2.5".parse::<White>(), Ok(White::Fixed(2.5)));
        assert!("0".parse::<White>().is_err());
        assert!("-1".parse::<White>().is_err());
        assert!("nan".parse::<White>().is_err());
    }
}
