//! The NatNet bitstream version: the only thing that tells how a frame is
//! laid out, since frames carry no version number of their own.

use std::fmt;

/// A NatNet bitstream version (major.minor). Build and revision never change
/// the layout, so they are not part of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Version {
    /// Major version: 2, 3 or 4 change the frame layout.
    pub major: u8,
    /// Minor version: some (2.6, 2.7, 4.1, 4.2) change it too.
    pub minor: u8,
}

impl Version {
    /// `major.minor`.
    pub const fn new(major: u8, minor: u8) -> Self {
        Version { major, minor }
    }

    /// `self >= major.minor`.
    pub fn at_least(self, major: u8, minor: u8) -> bool {
        (self.major, self.minor) >= (major, minor)
    }

    /// 4.1 added a u32 byte count after every frame section's count and
    /// after every description's type.
    pub fn has_section_sizes(self) -> bool {
        self.at_least(4, 1)
    }

    /// Parses "3.1" (a third component, "4.1.0", is accepted and ignored).
    pub fn parse(text: &str) -> Option<Version> {
        let mut parts = text.trim().split('.');
        let major = parts.next()?.trim().parse().ok()?;
        let minor = parts.next().map_or(Some(0), |m| m.trim().parse().ok())?;
        Some(Version { major, minor })
    }
}

impl fmt::Display for Version {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.major, self.minor)
    }
}

impl serde::Serialize for Version {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for Version {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// An optional version written as `""` when unset (TOML has no null):
/// `#[serde(with = "unset_if_empty")]`.
pub mod unset_if_empty {
    use super::Version;
    use serde::{Deserialize, Deserializer, Serializer};

    /// `""` for None.
    pub fn serialize<S: Serializer>(v: &Option<Version>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => s.collect_str(v),
            None => s.serialize_str(""),
        }
    }

    /// None for `""`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Version>, D::Error> {
        let text = String::deserialize(d)?;
        if text.trim().is_empty() {
            return Ok(None);
        }
        text.parse().map(Some).map_err(serde::de::Error::custom)
    }
}

impl std::str::FromStr for Version {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Version::parse(s).ok_or_else(|| format!("'{s}' is not a NatNet version like 3.1"))
    }
}

/// Every bitstream version whose frame layout differs from its predecessor's,
/// plus the later 4.x versions: what the round-trip tests and the server cover.
pub const SUPPORTED_VERSIONS: &[Version] = &[
    Version::new(2, 5),
    Version::new(2, 6),
    Version::new(2, 7),
    Version::new(2, 9),
    Version::new(2, 11),
    Version::new(3, 0),
    Version::new(3, 1),
    Version::new(4, 0),
    Version::new(4, 1),
    Version::new(4, 2),
    Version::new(4, 3),
];

/// The oldest bitstream this codec decodes (the 2.0 frame layout; 1.x differs).
pub const OLDEST_VERSION: Version = Version::new(2, 0);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_two_or_three_components_and_orders_by_major_then_minor() {
        assert_eq!(Version::parse("4.1.0"), Some(Version::new(4, 1)));
        assert_eq!(Version::parse(" 3 "), Some(Version::new(3, 0)));
        assert_eq!(Version::parse("three"), None);
        assert!(Version::new(2, 11) > Version::new(2, 9));
        assert!(Version::new(4, 1).has_section_sizes());
        assert!(!Version::new(4, 0).has_section_sizes());
        assert_eq!(Version::new(2, 11).to_string(), "2.11");
    }
}
