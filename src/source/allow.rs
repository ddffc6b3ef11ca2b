//! Which senders a listening socket accepts: a list of IP addresses and CIDR
//! ranges. Nothing beyond loopback is accepted unless the config says so.

use std::net::IpAddr;

use serde::Serialize;

use crate::error::{Error, Result};

/// One allowed range: an address and how many leading bits must match.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct IpRange {
    /// The network's address (or a single host's).
    pub addr: IpAddr,
    /// Leading bits that must match: 32 (IPv4) or 128 (IPv6) for one host.
    pub prefix: u8,
}

impl IpRange {
    /// Parses `192.168.1.5`, `192.168.1.0/24`, `::1`, `fe80::/10`.
    pub fn parse(text: &str) -> std::result::Result<IpRange, String> {
        let (addr, prefix) = match text.trim().split_once('/') {
            Some((a, p)) => (a, Some(p)),
            None => (text.trim(), None),
        };
        let addr: IpAddr = addr
            .parse()
            .map_err(|_| format!("'{text}' is not an IP address or CIDR range"))?;
        let max = if addr.is_ipv4() { 32 } else { 128 };
        let prefix = match prefix {
            None => max,
            Some(p) => match p.parse::<u8>() {
                Ok(p) if p <= max => p,
                _ => return Err(format!("'{text}': prefix length must be 0 to {max}")),
            },
        };
        Ok(IpRange { addr, prefix })
    }

    /// Whether `ip` lies in the range; an IPv4-mapped IPv6 address counts
    /// as the IPv4 address it carries.
    pub fn contains(&self, ip: IpAddr) -> bool {
        match (self.addr, canonical(ip)) {
            (IpAddr::V4(a), IpAddr::V4(b)) => prefix_eq(
                u128::from(u32::from(a)),
                u128::from(u32::from(b)),
                32,
                self.prefix,
            ),
            (IpAddr::V6(a), IpAddr::V6(b)) => {
                prefix_eq(u128::from(a), u128::from(b), 128, self.prefix)
            }
            _ => false,
        }
    }
}

impl std::fmt::Display for IpRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let max = if self.addr.is_ipv4() { 32 } else { 128 };
        if self.prefix == max {
            write!(f, "{}", self.addr)
        } else {
            write!(f, "{}/{}", self.addr, self.prefix)
        }
    }
}

/// An IPv4 sender seen on an IPv6 socket (`::ffff:a.b.c.d`) is matched as IPv4.
fn canonical(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
        v4 => v4,
    }
}

fn prefix_eq(a: u128, b: u128, bits: u32, prefix: u8) -> bool {
    let prefix = u32::from(prefix).min(bits);
    if prefix == 0 {
        return true;
    }
    let shift = bits - prefix;
    (a >> shift) == (b >> shift)
}

/// The senders a source accepts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct AllowList(pub Vec<IpRange>);

impl AllowList {
    /// 127.0.0.0/8 and ::1.
    pub fn loopback() -> Self {
        AllowList(vec![
            IpRange {
                addr: IpAddr::from([127, 0, 0, 0]),
                prefix: 8,
            },
            IpRange {
                addr: IpAddr::from(std::net::Ipv6Addr::LOCALHOST),
                prefix: 128,
            },
        ])
    }

    /// Parses config entries; `key` names the setting in errors.
    pub fn parse(key: &str, entries: &[String]) -> Result<Self> {
        entries
            .iter()
            .map(|e| IpRange::parse(e).map_err(|msg| Error::config(key, msg)))
            .collect::<Result<Vec<_>>>()
            .map(AllowList)
    }

    /// Whether a datagram from `ip` may be read.
    pub fn allows(&self, ip: IpAddr) -> bool {
        self.0.iter().any(|r| r.contains(ip))
    }
}

impl Default for AllowList {
    fn default() -> Self {
        AllowList::loopback()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn ranges_match_by_prefix() {
        let l = AllowList::parse(
            "k",
            &[
                "192.168.1.0/24".into(),
                "10.1.2.3".into(),
                "fe80::/10".into(),
            ],
        )
        .unwrap();
        assert!(l.allows(ip("192.168.1.200")));
        assert!(!l.allows(ip("192.168.2.1")));
        assert!(l.allows(ip("10.1.2.3")));
        assert!(!l.allows(ip("10.1.2.4")));
        assert!(l.allows(ip("fe80::1234")));
        assert!(!l.allows(ip("fec0::1")));
        assert!(
            l.allows(ip("::ffff:192.168.1.7")),
            "v4-mapped v6 matches v4 ranges"
        );
        assert!(AllowList::parse("k", &["0.0.0.0/0".into()])
            .unwrap()
            .allows(ip("8.8.8.8")));
    }

    #[test]
    fn default_is_loopback_only() {
        let l = AllowList::default();
        assert!(l.allows(ip("127.0.0.1")) && l.allows(ip("127.4.5.6")) && l.allows(ip("::1")));
        assert!(!l.allows(ip("192.168.1.1")) && !l.allows(ip("::2")));
    }

    #[test]
    fn bad_entries_name_the_key() {
        for bad in ["localhost", "10.0.0.0/33", "::/129", "1.2.3.4/x"] {
            let e = AllowList::parse("osc.allow", &[bad.into()]).unwrap_err();
            assert!(e.to_string().starts_with("config osc.allow:"), "{e}");
            assert_eq!(e.exit_code(), 2);
        }
    }
}
