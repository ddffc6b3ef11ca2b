//! Bad input, counted the same way by every socket that takes input from the
//! network (the OSC source, OSC control, NatNet, HTTP), so that `/status`,
//! `/metrics` and `record` show one set of kinds for all of them.

use std::sync::atomic::{AtomicU64, Ordering};

/// What was wrong with a datagram or connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BadInputKind {
    /// Decoded, but the content is not allowed: wrong argument types, a
    /// non-finite coordinate, a malformed request. Only that message is
    /// skipped.
    Invalid,
    /// Part of something is missing: a frame whose closing message was lost,
    /// a packet cut short, a request whose headers never came.
    Incomplete,
    /// From a sender outside the allow-list; dropped unread.
    NotAllowed,
    /// From an address other than the server we talk to (NatNet).
    WrongSender,
    /// Not the protocol at all, or nested or sized beyond the limits.
    FailedDecode,
}

impl BadInputKind {
    /// Every kind, in report order.
    pub const ALL: [BadInputKind; 5] = [
        BadInputKind::Invalid,
        BadInputKind::Incomplete,
        BadInputKind::NotAllowed,
        BadInputKind::WrongSender,
        BadInputKind::FailedDecode,
    ];

    /// The kind's name in `/status`, `/metrics` and reports.
    pub fn name(self) -> &'static str {
        match self {
            BadInputKind::Invalid => "invalid",
            BadInputKind::Incomplete => "incomplete",
            BadInputKind::NotAllowed => "not_allowed",
            BadInputKind::WrongSender => "wrong_sender",
            BadInputKind::FailedDecode => "failed_decode",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// Live counters of bad input by kind, for one socket.
#[derive(Debug, Default)]
pub struct BadInput([AtomicU64; 5]);

impl BadInput {
    /// Counts one bad input of `kind`.
    pub fn add(&self, kind: BadInputKind) {
        self.0[kind.index()].fetch_add(1, Ordering::Relaxed);
    }

    /// The count of `kind` so far.
    pub fn get(&self, kind: BadInputKind) -> u64 {
        self.0[kind.index()].load(Ordering::Relaxed)
    }

    /// Every kind with its count, zeros included (a zero is information too).
    pub fn counts(&self) -> Vec<(String, u64)> {
        BadInputKind::ALL
            .iter()
            .map(|&k| (k.name().to_string(), self.get(k)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_every_kind_apart() {
        let b = BadInput::default();
        b.add(BadInputKind::NotAllowed);
        b.add(BadInputKind::NotAllowed);
        b.add(BadInputKind::FailedDecode);
        assert_eq!(
            b.counts(),
            [
                ("invalid".to_string(), 0),
                ("incomplete".into(), 0),
                ("not_allowed".into(), 2),
                ("wrong_sender".into(), 0),
                ("failed_decode".into(), 1),
            ]
        );
    }
}
