//! Building a live source from the settings: the one place that `record`
//! and the daemon both use, so a source built for one is built the same way
//! for the other.

use std::net::SocketAddr;
use std::sync::Arc;

use crate::config::{Config, TransportSetting};
use crate::error::Result;
use crate::source::live::LiveSource;
use crate::source::natnet::{client::NatNetOptions, live::NatNetSource, Transport};
use crate::source::osc::{OscOptions, OscSource};

/// The NatNet client for `server` ("ADDRESS" or "ADDRESS:COMMAND_PORT";
/// `key` names where it came from in errors), with `[natnet]` settings.
pub fn natnet_source(
    config: &Config,
    server: &str,
    key: &str,
    transport: TransportSetting,
    bitstream: Option<crate::source::natnet::packet::Version>,
) -> Result<Arc<dyn LiveSource>> {
    let mut opts = NatNetOptions::from_config(&config.natnet);
    opts.set_server(server, key)?;
    opts.transport = match transport {
        TransportSetting::Unicast => Some(Transport::Unicast),
        TransportSetting::Multicast => Some(Transport::Multicast),
        TransportSetting::Auto => None,
    };
    opts.bitstream = bitstream;
    Ok(Arc::new(NatNetSource(opts)))
}

/// The OSC source with `[osc]` settings, listening on `bind` if given.
pub fn osc_source(config: &Config, bind: Option<SocketAddr>) -> Result<Arc<dyn LiveSource>> {
    let mut opts = OscOptions::from_settings(&config.osc)?;
    if let Some(bind) = bind {
        opts.bind = bind;
    }
    Ok(Arc::new(OscSource(opts)))
}
