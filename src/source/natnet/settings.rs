//! What the NatNet client can be told, typed once: the `[natnet]` section of
//! the config is this struct, `record`'s options and the daemon's
//! `natnet_server` / `natnet_transport` land here too, and nothing
//! downstream parses a string again.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::time::Duration;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::protocol::natnet::select::{MarkerSelection, UpAxisSetting};
use crate::protocol::natnet::session::SessionSettings;
use crate::protocol::natnet::{Transport, Version, DEFAULT_COMMAND_PORT};

/// The NatNet client's settings (`[natnet]`). The server's address and
/// the transport are given where the source is chosen (`--natnet`,
/// `daemon.natnet_server`, `--unicast`, `daemon.natnet_transport`), the
/// bitstream by `--natnet-version`, discovery only programmatically: those
/// are not keys of the section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NatNetSettings {
    /// The server's address; its command port is `command_port`.
    #[serde(skip)]
    pub server: Ipv4Addr,
    /// The server's command port (Motive: 1510).
    pub command_port: u16,
    /// Unicast or multicast; `auto` follows the server (3.0+ says) and, for
    /// 2.x servers, listens on both.
    #[serde(skip)]
    pub transport: TransportSetting,
    /// The local network interface multicast is joined on (an IPv4 address
    /// or a name such as `eth1`): labs often have one card for the cameras
    /// and one for the office. `any` lets the OS choose.
    pub interface: Interface,
    /// The multicast group; unset (`""`): what the server says (3.0+), else
    /// 239.255.42.99.
    #[serde(with = "unset_if_empty")]
    pub multicast_group: Option<Ipv4Addr>,
    /// The server's data port; unset (0): what the server says (3.0+),
    /// else 1511.
    #[serde(with = "unset_if_zero")]
    pub data_port: Option<u16>,
    /// Ask the server to stream this bitstream (unicast, server 3.0+).
    #[serde(skip)]
    pub bitstream: Option<Version>,
    /// Look for the server with a DISCOVERY broadcast instead of using
    /// `server` (never by default: it talks to the whole network).
    #[serde(skip)]
    pub discovery: bool,
    /// Where DISCOVERY goes (a broadcast address or a host).
    #[serde(skip)]
    pub discovery_address: Ipv4Addr,
    /// Which markers of a frame are tracked.
    pub markers: MarkerSelection,
    /// Which axis of the stream points up.
    pub up_axis: UpAxisSetting,
    /// Wait this long for the server's SERVERINFO before giving up.
    #[serde(rename = "connect_timeout_s", with = "seconds")]
    pub connect_timeout: Duration,
    /// Reconnect after this long without a datagram from the server.
    #[serde(rename = "silence_timeout_s", with = "seconds")]
    pub silence_timeout: Duration,
    /// Unicast keep-alive period.
    #[serde(rename = "keepalive_interval_s", with = "seconds")]
    pub keepalive_interval: Duration,
}

impl Default for NatNetSettings {
    fn default() -> Self {
        NatNetSettings {
            server: Ipv4Addr::LOCALHOST,
            command_port: DEFAULT_COMMAND_PORT,
            transport: TransportSetting::Auto,
            interface: Interface::Any,
            multicast_group: None,
            data_port: None,
            bitstream: None,
            discovery: false,
            discovery_address: Ipv4Addr::BROADCAST,
            markers: MarkerSelection::default(),
            up_axis: UpAxisSetting::default(),
            connect_timeout: Duration::from_secs(3),
            silence_timeout: Duration::from_secs(2),
            keepalive_interval: Duration::from_secs(1),
        }
    }
}

impl NatNetSettings {
    /// The server's command address.
    pub fn server_addr(&self) -> SocketAddr {
        SocketAddr::V4(SocketAddrV4::new(self.server, self.command_port))
    }

    /// Points the client at `ADDRESS` or `ADDRESS:COMMAND_PORT` (IPv4;
    /// without a port the configured command port stays).
    pub fn set_server(&mut self, text: &str) -> Result<(), String> {
        if let Ok(a) = text.parse::<SocketAddrV4>() {
            self.server = *a.ip();
            self.command_port = a.port();
        } else {
            self.server = text
                .parse()
                .map_err(|_| format!("'{text}' is not an IPv4 address or ADDRESS:PORT"))?;
        }
        Ok(())
    }

    /// Range checks, each naming the key and its allowed range.
    pub fn validate(&self) -> crate::error::Result<()> {
        use crate::error::{check_range, Error};
        let s = |d: Duration| d.as_secs_f64();
        check_range(
            "natnet.connect_timeout_s",
            s(self.connect_timeout),
            0.1,
            60.0,
        )?;
        check_range(
            "natnet.silence_timeout_s",
            s(self.silence_timeout),
            0.1,
            60.0,
        )?;
        check_range(
            "natnet.keepalive_interval_s",
            s(self.keepalive_interval),
            0.05,
            10.0,
        )?;
        if let Some(g) = self.multicast_group.filter(|g| !g.is_multicast()) {
            return Err(Error::config(
                "natnet.multicast_group",
                format!("{g} is not a multicast address (224.0.0.0 to 239.255.255.255)"),
            ));
        }
        if self.command_port == 0 {
            return Err(Error::config("natnet.command_port", "0 is not a port"));
        }
        Ok(())
    }

    /// What the protocol session needs of these.
    pub fn session(&self) -> SessionSettings {
        SessionSettings {
            transport: self.transport.fixed(),
            multicast_group: self.multicast_group,
            data_port: self.data_port,
            bitstream: self.bitstream,
            markers: self.markers,
            up_axis: self.up_axis,
            connect_timeout: self.connect_timeout,
            silence_timeout: self.silence_timeout,
            keepalive_interval: self.keepalive_interval,
        }
    }
}

/// `natnet.transport`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TransportSetting {
    /// Follow the server.
    #[default]
    Auto,
    /// Frames sent to this client only.
    Unicast,
    /// Frames multicast to the group.
    Multicast,
}

impl TransportSetting {
    /// The transport insisted on, if any.
    pub fn fixed(self) -> Option<Transport> {
        match self {
            TransportSetting::Auto => None,
            TransportSetting::Unicast => Some(Transport::Unicast),
            TransportSetting::Multicast => Some(Transport::Multicast),
        }
    }
}

/// A local network interface, by address or by name.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Interface {
    /// Whichever the OS routes the group to.
    #[default]
    Any,
    /// The interface with this IPv4 address.
    Address(Ipv4Addr),
    /// The interface with this name (`eth1`, `enp3s0`).
    Name(String),
}

impl std::str::FromStr for Interface {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        if s.is_empty() || s == "any" || s == "0.0.0.0" {
            return Ok(Interface::Any);
        }
        if let Ok(a) = s.parse::<Ipv4Addr>() {
            return Ok(Interface::Address(a));
        }
        // Linux names: at most 15 bytes, no '/' or whitespace; this also
        // keeps the name safe to look up under /sys/class/net.
        let ok = s.len() <= 15
            && s.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-_.:@".contains(&b));
        if ok && !s.starts_with('.') {
            Ok(Interface::Name(s.to_string()))
        } else {
            Err(format!(
                "'{s}' is neither an IPv4 address nor a network interface name"
            ))
        }
    }
}

impl std::fmt::Display for Interface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Interface::Any => f.write_str("any"),
            Interface::Address(a) => write!(f, "{a}"),
            Interface::Name(n) => f.write_str(n),
        }
    }
}

impl Serialize for Interface {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for Interface {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

/// An optional address written as `""` when unset (TOML has no null).
mod unset_if_empty {
    use std::net::Ipv4Addr;

    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<S: Serializer>(a: &Option<Ipv4Addr>, s: S) -> Result<S::Ok, S::Error> {
        match a {
            Some(a) => s.collect_str(a),
            None => s.serialize_str(""),
        }
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<Ipv4Addr>, D::Error> {
        let text = String::deserialize(d)?;
        if text.trim().is_empty() {
            return Ok(None);
        }
        text.trim()
            .parse()
            .map(Some)
            .map_err(|_| serde::de::Error::custom(format!("'{text}' is not an IPv4 address")))
    }
}

/// An optional port written as 0 when unset.
mod unset_if_zero {
    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<S: Serializer>(p: &Option<u16>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u16(p.unwrap_or(0))
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u16>, D::Error> {
        Ok(Some(u16::deserialize(d)?).filter(|&p| p != 0))
    }
}

/// Durations written as seconds (`connect_timeout_s = 0.5`).
mod seconds {
    use std::time::Duration;

    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(d.as_secs_f64())
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Duration, D::Error> {
        let x = f64::deserialize(d)?;
        Duration::try_from_secs_f64(x)
            .map_err(|_| serde::de::Error::custom(format!("{x}: not a duration in seconds")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_natnet_section_with_typed_values() {
        let s: NatNetSettings = toml::from_str(
            "command_port = 4510\ninterface = \"eth1\"\n\
             multicast_group = \"239.1.2.3\"\ndata_port = 9511\nup_axis = \"z\"\n\
             connect_timeout_s = 0.5\n",
        )
        .unwrap();
        assert_eq!(s.server_addr().to_string(), "127.0.0.1:4510");
        assert_eq!(s.data_port, Some(9511));
        assert_eq!(s.interface, Interface::Name("eth1".into()));
        assert_eq!(s.multicast_group, Some(Ipv4Addr::new(239, 1, 2, 3)));
        assert_eq!(s.connect_timeout, Duration::from_millis(500));
        assert_eq!(s.up_axis, UpAxisSetting::Z);
        assert!(s.validate().is_ok());
        let unset: NatNetSettings =
            toml::from_str("multicast_group = \"\"\ndata_port = 0").unwrap();
        assert_eq!((unset.multicast_group, unset.data_port), (None, None));
        let bad: NatNetSettings = toml::from_str("multicast_group = \"10.0.0.1\"").unwrap();
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("natnet.multicast_group"), "{e}");
        assert!(toml::from_str::<NatNetSettings>("interface = \"../etc\"").is_err());
        assert!(toml::from_str::<NatNetSettings>("transport = \"unicast\"").is_err());
        assert_eq!(
            "192.168.1.4".parse(),
            Ok(Interface::Address(Ipv4Addr::new(192, 168, 1, 4)))
        );
    }

    #[test]
    fn a_server_is_an_address_with_or_without_its_command_port() {
        let mut s = NatNetSettings::default();
        s.set_server("10.1.2.3").unwrap();
        assert_eq!(s.server_addr().to_string(), "10.1.2.3:1510");
        s.set_server("10.1.2.4:4000").unwrap();
        assert_eq!(s.server_addr().to_string(), "10.1.2.4:4000");
        assert!(s.set_server("motive.local").is_err());
    }
}
