//! `daemon.osc_control`: `/treemocap/rebuild` over OSC, from senders in
//! `osc.allow` only. Decoded by the same [`parse_datagram`] as the OSC source,
//! with the same depth and size limits: one datagram must never stop the
//! daemon. Bad input is counted by kind and warned about once per kind every
//! 10 s.

use std::sync::Arc;
use std::time::Duration;

use rosc::OscPacket;
use tokio::net::UdpSocket;

use crate::protocol::osc::{parse_datagram, MAX_DATAGRAM_BYTES};
use crate::shutdown::Shutdown;
use crate::source::allow::AllowList;
use crate::source::bad_input::{BadInput, BadInputKind};
use crate::throttle::LogThrottle;

/// The address that asks for a new tree.
const REBUILD: &str = "/treemocap/rebuild";

/// True when the packet holds a rebuild request anywhere. Recursion is
/// bounded: `parse_datagram` refused anything nested deeper than 8.
fn asks_rebuild(p: &OscPacket) -> bool {
    match p {
        OscPacket::Message(m) => m.addr == REBUILD,
        OscPacket::Bundle(b) => b.content.iter().any(asks_rebuild),
    }
}

/// Receives on `socket` until `stop`; calls `rebuild` on each request from
/// an allowed sender and counts the rest in `bad`.
pub(crate) async fn run(
    socket: UdpSocket,
    allow: AllowList,
    rebuild: impl Fn(),
    bad: Arc<BadInput>,
    stop: Shutdown,
) {
    let throttle = LogThrottle::default();
    let mut buf = vec![0u8; MAX_DATAGRAM_BYTES + 1];
    let mut flush = tokio::time::interval(Duration::from_secs(1));
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => {
                let Ok((n, from)) = r else { continue };
                if !allow.allows(from.ip()) {
                    bad.add(BadInputKind::NotAllowed);
                    throttle.warn("osc control: senders not in osc.allow", || {
                        format!("osc control: {from} is not in osc.allow; ignored")
                    });
                    continue;
                }
                match parse_datagram(buf.get(..n).unwrap_or(&[])) {
                    Ok(p) if asks_rebuild(&p) => rebuild(),
                    Ok(_) => {
                        bad.add(BadInputKind::Invalid);
                        throttle.warn("osc control: messages other than /treemocap/rebuild", || {
                            format!("osc control: datagram from {from} holds no {REBUILD}; ignored")
                        });
                    }
                    Err(e) => {
                        bad.add(BadInputKind::FailedDecode);
                        throttle.warn("osc control: datagrams that are not OSC", || {
                            format!("osc control: from {from}: {e}")
                        });
                    }
                }
            }
            _ = flush.tick() => throttle.flush(),
            _ = stop.triggered() => break,
        }
    }
    throttle.finish();
}
