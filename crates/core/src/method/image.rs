//! [`ImageId`]: one image a run makes, the key of its metrics and seconds.

use std::str::FromStr;

use super::Method;

/// One image a run makes: a method's, or that image denoised after it
/// (`METHOD+oidn`). Its name ([`std::fmt::Display`], and its form in JSON)
/// is the file name; metrics, seconds and reports are keyed by it. Ordered
/// by name, as the report's maps always were.
///
/// ```
/// use pathdensity_core::method::{ImageId, Method};
/// let id: ImageId = "filtered+oidn".parse().unwrap();
/// assert_eq!(id, ImageId { method: Method::Filtered, denoised: true });
/// assert_eq!(ImageId::from(Method::Mean).to_string(), "mean");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageId {
    pub method: Method,
    /// Denoised by the run's `denoise` after `method`.
    pub denoised: bool,
}

/// The suffix of a denoised image's name.
const DENOISED: &str = "+oidn";

impl From<Method> for ImageId {
    fn from(method: Method) -> ImageId {
        ImageId {
            method,
            denoised: false,
        }
    }
}

impl ImageId {
    /// Every image a run can make in the canonical order: each method's
    /// ([`Method::ALL`]), then each denoised.
    pub fn all() -> impl Iterator<Item = ImageId> {
        [false, true].into_iter().flat_map(|denoised| {
            Method::ALL
                .into_iter()
                .map(move |method| ImageId { method, denoised })
        })
    }
}

impl std::fmt::Display for ImageId {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.method.name())?;
        if self.denoised {
            f.write_str(DENOISED)?;
        }
        Ok(())
    }
}

impl FromStr for ImageId {
    type Err = String;
    fn from_str(s: &str) -> Result<ImageId, String> {
        let (name, denoised) = match s.strip_suffix(DENOISED) {
            Some(name) => (name, true),
            None => (s, false),
        };
        Ok(ImageId {
            method: name.parse()?,
            denoised,
        })
    }
}

impl Ord for ImageId {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        let key = |i: &ImageId| (i.method.name(), i.denoised);
        // "a" < "a+oidn" < "a_b" by name; by (name, denoised) the same
        // unless a name continues with a character below '+', which none does.
        key(self).cmp(&key(other))
    }
}

impl PartialOrd for ImageId {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl serde::Serialize for ImageId {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for ImageId {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<ImageId, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}
