//! Building a live source from the settings: the one place that `record`
//! and the daemon both use, so a source built for one is built the same way
//! for the other.

use std::net::SocketAddr;
use std::sync::Arc;

use crate::config::Config;
use crate::error::{Error, Result};
use crate::source::live::LiveSource;
use crate::source::natnet::live::NatNetSource;
use crate::source::natnet::settings::NatNetSettings;
use crate::source::osc::{OscOptions, OscSource};

/// The NatNet client for `server` ("ADDRESS" or "ADDRESS:COMMAND_PORT";
/// `key` names where it came from in errors) with `settings` (the `[natnet]`
/// section with the command's own options applied).
pub fn natnet_source(
    mut settings: NatNetSettings,
    server: &str,
    key: &str,
) -> Result<Arc<dyn LiveSource>> {
    settings
        .set_server(server)
        .map_err(|e| Error::config(key, e))?;
    settings.validate()?;
    Ok(Arc::new(NatNetSource::new(settings)))
}

/// The OSC source with `[osc]` settings, listening on `bind` if given.
pub fn osc_source(config: &Config, bind: Option<SocketAddr>) -> Result<Arc<dyn LiveSource>> {
    let mut opts = OscOptions::from_settings(&config.osc)?;
    if let Some(bind) = bind {
        opts.bind = bind;
    }
    Ok(Arc::new(OscSource(opts)))
}
