//! [`MethodSet`]: the images a run makes, as one bit a method.

use super::{Made, Method, TABLE};

/// A set of methods that always holds mean and filtered, which every run
/// makes. Iterates in the canonical order of [`Method::ALL`]; in JSON a
/// list of names. As many methods as the table has fit.
///
/// ```
/// use pathdensity_core::config::{Method, MethodSet};
/// let s: MethodSet = [Method::Rwmc].into_iter().collect();
/// let v: Vec<Method> = s.iter().collect();
/// assert_eq!(v, [Method::Mean, Method::Filtered, Method::Rwmc]);
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct MethodSet([u64; WORDS]);

/// Words of a [`MethodSet`]: one bit a method.
const WORDS: usize = Method::COUNT.div_ceil(64);

impl MethodSet {
    const EMPTY: MethodSet = MethodSet([0; WORDS]);

    /// Mean and filtered.
    pub const CORE: MethodSet = MethodSet::EMPTY.with(Method::Mean).with(Method::Filtered);

    /// Every method of the table.
    pub const ALL: MethodSet = {
        let mut s = MethodSet::EMPTY;
        let mut i = 0;
        while i < Method::COUNT {
            s = s.with(TABLE[i].method);
            i += 1;
        }
        s
    };

    /// Every method that needs no OIDN: what every machine can make.
    pub const NO_OIDN: MethodSet = MethodSet::without_oidn(false);

    /// What a run makes unless told otherwise, wherever it runs: each
    /// row made by default that needs no OIDN. [`MethodSet::default_here`]
    /// swaps in the OIDN rows when this process finds OIDN.
    pub const DEFAULT: MethodSet = MethodSet::without_oidn(true);

    /// The rows that need no OIDN, and only those made by default if
    /// `by_default`.
    const fn without_oidn(by_default: bool) -> MethodSet {
        let mut s = MethodSet::CORE;
        let mut i = 0;
        while i < Method::COUNT {
            let row = &TABLE[i];
            if !row.needs.oidn && (!by_default || matches!(row.default, Made::ByDefault)) {
                s = s.with(row.method);
            }
            i += 1;
        }
        s
    }

    /// [`MethodSet::DEFAULT`] with the default rows this process can make
    /// besides, OIDN's where it finds it
    /// ([`crate::imagespace::oidn::library`]), each in place of the image
    /// its row names: what the commands make when no `--methods` is given.
    pub fn default_here() -> MethodSet {
        TABLE
            .iter()
            .filter(|r| r.method.available())
            .fold(MethodSet::DEFAULT, |s, r| match r.default {
                Made::ByName => s,
                Made::ByDefault => s.with(r.method),
                Made::InsteadOf(other) => s.with(r.method).without(other),
            })
    }

    pub const fn contains(self, m: Method) -> bool {
        let i = m as usize;
        self.0[i / 64] & (1 << (i % 64)) != 0
    }

    /// This set without `m` (mean and filtered stay).
    pub const fn without(self, m: Method) -> MethodSet {
        let i = m as usize;
        let mut words = self.0;
        words[i / 64] &= !(1 << (i % 64));
        MethodSet(words).with(Method::Mean).with(Method::Filtered)
    }

    /// This set and `m`.
    pub const fn with(self, m: Method) -> MethodSet {
        let i = m as usize;
        let mut words = self.0;
        words[i / 64] |= 1 << (i % 64);
        MethodSet(words)
    }

    /// Every method this process can make ([`Method::available`]): what
    /// `all` names in a list of methods.
    pub fn available() -> MethodSet {
        Method::ALL.into_iter().filter(|m| m.available()).collect()
    }

    /// A list of method names, where `all` stands for
    /// [`MethodSet::available`]; mean and filtered are always in.
    pub fn from_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Result<MethodSet, String> {
        names.into_iter().try_fold(MethodSet::CORE, |set, name| {
            Ok(match name {
                ALL_NAME => set.union(MethodSet::available()),
                _ => set.with(name.parse()?),
            })
        })
    }

    /// The methods of either set.
    pub fn union(self, other: MethodSet) -> MethodSet {
        MethodSet(std::array::from_fn(|w| self.0[w] | other.0[w]))
    }

    /// The methods in the canonical order.
    pub fn iter(self) -> impl Iterator<Item = Method> {
        Method::ALL.into_iter().filter(move |&m| self.contains(m))
    }
}

/// The name that stands for every available method in a list of methods.
const ALL_NAME: &str = "all";

/// A comma-separated list of names ([`MethodSet::from_names`]), as
/// `--methods` takes it.
impl std::str::FromStr for MethodSet {
    type Err = String;
    fn from_str(s: &str) -> Result<MethodSet, String> {
        let names: Vec<&str> = s.split(',').map(str::trim).collect();
        if names.contains(&"") {
            return Err(format!("{s:?} names no method"));
        }
        MethodSet::from_names(names)
    }
}

impl FromIterator<Method> for MethodSet {
    fn from_iter<I: IntoIterator<Item = Method>>(iter: I) -> MethodSet {
        iter.into_iter().fold(MethodSet::CORE, MethodSet::with)
    }
}

impl std::fmt::Debug for MethodSet {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl serde::Serialize for MethodSet {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

impl<'de> serde::Deserialize<'de> for MethodSet {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<MethodSet, D::Error> {
        let names = Vec::<String>::deserialize(d)?;
        MethodSet::from_names(names.iter().map(String::as_str)).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_names_every_available_method() {
        let s: MethodSet = "median, all".parse().unwrap();
        assert_eq!(s, MethodSet::available());
        assert!(s.contains(Method::Rwmc) && s.contains(Method::Statmc));
        assert_eq!(s.contains(Method::Oidn), Method::Oidn.available());
        let json: MethodSet = serde_json::from_str(r#"["all"]"#).unwrap();
        assert_eq!(json, s);
        let few: MethodSet = "rwmc".parse().unwrap();
        assert_eq!(
            few.iter().collect::<Vec<_>>(),
            [Method::Mean, Method::Filtered, Method::Rwmc]
        );
        assert!(
            "rwmc,nope"
                .parse::<MethodSet>()
                .unwrap_err()
                .contains("unknown method")
        );
        assert!("".parse::<MethodSet>().is_err() && "rwmc,".parse::<MethodSet>().is_err());
        // By default one recommended image: guided_oidn in guided's place.
        let here = MethodSet::default_here();
        assert!(here.contains(Method::FilteredEnergy));
        assert_ne!(
            here.contains(Method::Guided),
            here.contains(Method::GuidedOidn)
        );
        assert_eq!(
            here.contains(Method::GuidedOidn),
            Method::GuidedOidn.available()
        );
        assert!(!MethodSet::NO_OIDN.iter().any(Method::needs_oidn));
        assert!(MethodSet::NO_OIDN.contains(Method::Rwmc));
    }
}
