//! The live NatNet client's I/O: tokio UDP sockets around the protocol
//! [`Session`], which decides everything (see its docs). This file only
//! opens sockets, moves datagrams between them and the session with the
//! time, carries out the session's actions, and publishes its state to a
//! [`NatNetStatus`] that `record` and the daemon read while it runs.
//!
//! Sockets:
//! - the **command socket** (an ephemeral port on 0.0.0.0; the OS picks the
//!   route to the server): CONNECT, requests and their replies, and unicast
//!   frames, which the server sends from its data port to this socket;
//! - the **data socket** for multicast, opened when the session says so:
//!   bound to the group and data port themselves (so only datagrams sent to
//!   the group arrive) with address reuse (several clients on one machine),
//!   the group joined on the configured interface.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use serde::Serialize;
use socket2::{Domain, InterfaceIndexOrAddress, Protocol, Socket, Type};
use tokio::net::UdpSocket;
use tokio::sync::watch;

use super::settings::{Interface, NatNetSettings};
use crate::error::{Error, Result};
use crate::protocol::natnet::select::UpAxis;
use crate::protocol::natnet::session::{
    our_sender, Action, Channel, Counters, FrameRate, ServerIdentity, Session, SessionError, State,
};
use crate::protocol::natnet::{decode, encode, Connect, Packet, ServerInfo, Version};
use crate::source::channel::FrameSink;

/// What the client is doing, readable while it runs (`/status`, `record`).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ClientStatus {
    /// The session's state; None before the client started.
    pub state: Option<State>,
    /// The server, once it answered.
    pub server: Option<ServerIdentity>,
    /// The frame rate and where it came from, once known.
    pub frame_rate: Option<FrameRate>,
    /// The stream's up axis, once known.
    pub up_axis: Option<UpAxis>,
    /// Frames, markers and bad datagrams by kind.
    pub counters: Counters,
}

/// The shared, live [`ClientStatus`] of one client.
#[derive(Debug, Default)]
pub struct NatNetStatus(Mutex<ClientStatus>);

impl NatNetStatus {
    /// A copy of the current status.
    pub fn snapshot(&self) -> ClientStatus {
        self.lock().clone()
    }

    /// The status holds plain counters that are whole after every update,
    /// so a panic elsewhere while it was locked leaves nothing half-written:
    /// a poisoned lock is taken as it is.
    fn lock(&self) -> MutexGuard<'_, ClientStatus> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn publish(&self, s: &Session) {
        let mut g = self.lock();
        g.state = Some(s.state());
        g.server = s.server();
        g.frame_rate = s.frame_rate();
        g.up_axis = s.up_axis();
        g.counters = *s.counters();
    }
}

/// What a finished client did.
#[derive(Debug, Clone, PartialEq)]
pub struct ClientReport {
    /// "Motive 2.1.0.0 at 192.168.0.106:1510".
    pub server: String,
    /// The bitstream version frames were last decoded with.
    pub version: Option<Version>,
    /// The counters at the end.
    pub counters: Counters,
    /// The frame rate used, if known.
    pub frame_rate: Option<FrameRate>,
}

impl From<SessionError> for Error {
    fn from(e: SessionError) -> Self {
        Error::Runtime(e.to_string())
    }
}

/// Runs the client until `shutdown` turns true or the sink's receiver is
/// gone; see the module docs.
pub async fn run(
    settings: &NatNetSettings,
    status: &NatNetStatus,
    sink: FrameSink,
    mut shutdown: watch::Receiver<bool>,
) -> Result<ClientReport> {
    let server = server_address(settings).await?;
    // The OS picks the route to the server; `interface` names the multicast one.
    let cmd = socket(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0), false)
        .and_then(tokio_socket)
        .map_err(|e| Error::Runtime(format!("cannot open a NatNet command socket: {e}")))?;
    let mut io = Io {
        settings,
        cmd,
        data: None,
        sink,
        arrived: Instant::now(),
    };
    let mut session = Session::new(settings.session(), server, Instant::now());
    let mut buf = vec![0u8; 65536];
    let mut dbuf = vec![0u8; 65536];
    loop {
        io.perform(&mut session, status).await?;
        status.publish(&session);
        if session.state() == State::Closed {
            break;
        }
        let timeout = session.poll_timeout();
        tokio::select! {
            changed = shutdown.changed() => {
                if changed.is_err() || *shutdown.borrow() {
                    session.close(Instant::now());
                }
            }
            r = io.cmd.recv_from(&mut buf) => {
                // ICMP errors (the server's port closed) surface here; the
                // session's silence timer deals with a server that is gone.
                if let Ok((n, from)) = r {
                    io.arrived = Instant::now();
                    session.handle(io.arrived, from, Channel::Command, &buf[..n]);
                }
            }
            r = recv(&io.data, &mut dbuf) => {
                if let Ok((n, from)) = r {
                    io.arrived = Instant::now();
                    session.handle(io.arrived, from, Channel::Data, &dbuf[..n]);
                }
            }
            _ = sleep_until(timeout) => session.on_timeout(Instant::now()),
        }
    }
    Ok(report(&session))
}

/// The sockets and the sink, which the session's actions act on.
struct Io<'a> {
    settings: &'a NatNetSettings,
    cmd: UdpSocket,
    data: Option<UdpSocket>,
    sink: FrameSink,
    /// When the datagram being handled arrived: its frames' latency on
    /// `/status` counts from there, so the decoding is part of it.
    arrived: Instant,
}

impl Io<'_> {
    /// Carries out every queued action. A fatal one ends the client with
    /// its error; a sink whose receiver is gone closes the session.
    async fn perform(&mut self, session: &mut Session, status: &NatNetStatus) -> Result<()> {
        while let Some(action) = session.poll_action() {
            match action {
                Action::Send { to, datagram } => {
                    if let Err(e) = self.cmd.send_to(&datagram, to).await {
                        tracing::debug!("cannot send to {to}: {e}");
                    }
                }
                Action::JoinMulticast {
                    group,
                    port,
                    required,
                } => match join(&self.settings.interface, group, port) {
                    Ok(s) => self.data = Some(s),
                    Err(e) if !required => {
                        tracing::warn!("{e}; listening for unicast frames only")
                    }
                    Err(e) => return Err(e),
                },
                Action::Frame(f) => {
                    if !self.sink.push_arrived(f, self.arrived) {
                        session.close(Instant::now());
                    }
                }
                Action::Fail(SessionError::NoAnswer { server, after }) => {
                    let why = if refused(server).await {
                        "nothing is listening there (connection refused)"
                    } else {
                        "no answer (is Motive streaming, and is the address right?)"
                    };
                    return Err(Error::Runtime(format!(
                        "NatNet server {server}: {why} after {:.1} s",
                        after.as_secs_f64()
                    )));
                }
                Action::Fail(e) => return Err(e.into()),
                // Published before the frames that follow are pushed, so a
                // reader of the first frame (record's log header) sees them.
                Action::Connected(_) | Action::VersionChanged { .. } | Action::FrameRate(_) => {
                    status.publish(session)
                }
            }
        }
        Ok(())
    }
}

fn report(s: &Session) -> ClientReport {
    let server = match s.server() {
        Some(i) => {
            let v = i.app_version;
            format!(
                "{} {}.{}.{}.{} at {}",
                i.name,
                v[0],
                v[1],
                v[2],
                v[3],
                s.server_addr()
            )
        }
        None => s.server_addr().to_string(),
    };
    ClientReport {
        server,
        version: s.server().map(|i| i.version),
        counters: *s.counters(),
        frame_rate: s.frame_rate(),
    }
}

/// The configured server, or one found by DISCOVERY when allowed.
async fn server_address(settings: &NatNetSettings) -> Result<SocketAddr> {
    if !settings.discovery {
        return Ok(settings.server_addr());
    }
    let local = match &settings.interface {
        Interface::Address(a) => *a,
        _ => Ipv4Addr::UNSPECIFIED,
    };
    let (from, info) = discover(
        local,
        settings.discovery_address,
        settings.command_port,
        settings.connect_timeout,
    )
    .await?;
    tracing::info!("discovered {} at {from}", info.sender.name);
    Ok(SocketAddr::new(from.ip(), settings.command_port))
}

async fn recv(s: &Option<UdpSocket>, buf: &mut [u8]) -> std::io::Result<(usize, SocketAddr)> {
    match s {
        Some(s) => s.recv_from(buf).await,
        None => std::future::pending().await,
    }
}

async fn sleep_until(t: Option<Instant>) {
    match t {
        Some(t) => tokio::time::sleep_until(t.into()).await,
        None => std::future::pending().await,
    }
}

fn socket(bind: SocketAddrV4, reuse: bool) -> std::io::Result<Socket> {
    let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    if reuse {
        s.set_reuse_address(true)?;
        #[cfg(unix)]
        s.set_reuse_port(true)?;
    }
    // 1000 frames/s of 1000 markers is 26 MB/s; the kernel may cap this,
    // and a smaller buffer only risks loss, so a refusal is not an error.
    let _ = s.set_recv_buffer_size(8 << 20);
    s.set_nonblocking(true)?;
    s.bind(&bind.into())?;
    Ok(s)
}

fn tokio_socket(s: Socket) -> std::io::Result<UdpSocket> {
    UdpSocket::from_std(s.into())
}

/// The kernel's index of the interface called `name` (Linux).
fn interface_index(name: &str) -> Result<u32> {
    // `Interface` names are checked to hold no '/', so this stays in /sys.
    let path = format!("/sys/class/net/{name}/ifindex");
    std::fs::read_to_string(&path)
        .ok()
        .and_then(|t| t.trim().parse().ok())
        .ok_or_else(|| {
            Error::Runtime(format!(
                "there is no network interface named '{name}' (see `ip link`)"
            ))
        })
}

/// Binds the data socket to the group and port (only datagrams sent to the
/// group arrive; unix) with address reuse, and joins the group on `iface`.
fn join(iface: &Interface, group: Ipv4Addr, port: u16) -> Result<UdpSocket> {
    let bind_to = if cfg!(unix) {
        group
    } else {
        Ipv4Addr::UNSPECIFIED
    };
    let s = socket(SocketAddrV4::new(bind_to, port), true).map_err(|e| {
        Error::Runtime(format!(
            "cannot bind the NatNet data port {group}:{port}: {e}"
        ))
    })?;
    let which = match iface {
        Interface::Any => InterfaceIndexOrAddress::Address(Ipv4Addr::UNSPECIFIED),
        Interface::Address(a) => InterfaceIndexOrAddress::Address(*a),
        Interface::Name(n) => InterfaceIndexOrAddress::Index(interface_index(n)?),
    };
    let shown = match iface {
        Interface::Any => "0.0.0.0 (any)".to_string(),
        other => other.to_string(),
    };
    s.join_multicast_v4_n(&group, &which).map_err(|e| {
        Error::Runtime(format!(
            "cannot join multicast group {group} on interface {shown}: {e} (is the interface up, \
             with a multicast route? try --unicast)"
        ))
    })?;
    tokio_socket(s).map_err(|e| Error::Runtime(format!("data socket: {e}")))
}

/// Finds a server with a DISCOVERY datagram; returns its address and info.
pub async fn discover(
    local: Ipv4Addr,
    to: Ipv4Addr,
    command_port: u16,
    timeout: Duration,
) -> Result<(SocketAddr, ServerInfo)> {
    let s = socket(SocketAddrV4::new(local, 0), false)
        .and_then(|s| {
            s.set_broadcast(true)?;
            Ok(s)
        })
        .and_then(tokio_socket)
        .map_err(|e| {
            Error::Runtime(format!(
                "cannot open a socket on {local} for discovery: {e}"
            ))
        })?;
    let msg = encode(
        &Packet::Discovery(Connect::Sender {
            sender: our_sender(),
            options: None,
            spare: Vec::new(),
        }),
        Version::new(4, 1),
    )
    .map_err(|e| Error::Runtime(e.to_string()))?;
    let deadline = Instant::now() + timeout;
    let mut buf = vec![0u8; 2048];
    while Instant::now() < deadline {
        let _ = s.send_to(&msg, (to, command_port)).await;
        let wait = tokio::time::timeout(Duration::from_millis(500), s.recv_from(&mut buf)).await;
        if let Ok(Ok((n, from))) = wait {
            if let Some(Ok(Packet::ServerInfo(info))) =
                buf.get(..n).map(|d| decode(d, Version::new(3, 0)))
            {
                return Ok((from, info));
            }
        }
    }
    Err(Error::Runtime(format!(
        "no NatNet server answered a discovery broadcast to {to}:{command_port} within {:.1} s",
        timeout.as_secs_f64()
    )))
}

/// Tells "nothing listening" (an ICMP port-unreachable) from "no answer":
/// a connected UDP socket sees the ICMP error as ECONNREFUSED.
async fn refused(server: SocketAddr) -> bool {
    let Ok(s) = UdpSocket::bind("0.0.0.0:0").await else {
        return false;
    };
    if s.connect(server).await.is_err() {
        return false;
    }
    let Ok(ka) = encode(&Packet::KeepAlive, Version::new(3, 0)) else {
        return false;
    };
    let mut buf = [0u8; 64];
    for _ in 0..2 {
        if let Err(e) = s.send(&ka).await {
            return e.kind() == std::io::ErrorKind::ConnectionRefused;
        }
        if let Ok(Err(e)) = tokio::time::timeout(Duration::from_millis(200), s.recv(&mut buf)).await
        {
            return e.kind() == std::io::ErrorKind::ConnectionRefused;
        }
    }
    false
}
