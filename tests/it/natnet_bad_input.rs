//! The client fed bad datagrams by a hand-driven fake server on real UDP
//! sockets: each is counted by kind and logged, the client carries on and
//! still delivers the good frames that follow.

use std::sync::atomic::Ordering;
use std::time::Duration;

use tokio::net::UdpSocket;
use treemocap::source::channel::frame_channel;
use treemocap::source::natnet::client::{self, NatNetOptions};
use treemocap::source::natnet::packet::*;
use treemocap::source::natnet::Transport;

fn good_frame(n: i32) -> Vec<u8> {
    let f = FrameOfData {
        frame_number: n,
        labeled_markers: vec![LabeledMarker {
            id: 7,
            position: [0.25, 1.5, -0.5],
            params: MARKER_UNLABELED,
            ..Default::default()
        }],
        timestamp: n as f64 / 100.0,
        ..Default::default()
    };
    encode(&Packet::FrameOfData(Box::new(f)), Version::new(3, 1)).unwrap()
}

#[test]
fn bad_datagrams_are_counted_and_the_client_carries_on() {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let server = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let data_port = std::net::UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let opts = NatNetOptions {
            command_port: server.local_addr().unwrap().port(),
            // Multicast so that there is a data channel; the fake server
            // sends to it directly (a multicast socket also gets unicast).
            transport: Some(Transport::Multicast),
            local: "127.0.0.1".parse().unwrap(),
            data_port: Some(data_port),
            ..Default::default()
        };
        let stats = opts.stats.clone();
        let (sink, rx) = frame_channel(100);
        let (stop, shutdown) = tokio::sync::watch::channel(false);
        let client = tokio::spawn(async move { client::run(&opts, sink, shutdown).await });

        let mut buf = [0u8; 2048];
        let (n, from) = server.recv_from(&mut buf).await.unwrap();
        assert!(matches!(
            decode(&buf[..n], Version::new(3, 1)),
            Ok(Packet::Connect(_))
        ));
        let info = ServerInfo {
            sender: Sender {
                name: "fake".into(),
                version: [1, 0, 0, 0],
                natnet_version: [3, 1, 0, 0],
            },
            connection: Some(ServerConnection {
                clock_frequency: 1_000_000,
                data_port,
                multicast: true,
                multicast_group: [239, 255, 42, 99],
            }),
        };
        server
            .send_to(
                &encode(&Packet::ServerInfo(info.clone()), Version::new(3, 1)).unwrap(),
                from,
            )
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(200)).await;

        let data = ("127.0.0.1", data_port);
        let frame = good_frame(1);
        // Truncated datagram.
        server
            .send_to(&frame[..frame.len() - 9], data)
            .await
            .unwrap();
        // nDataBytes says less than the content.
        let mut short = frame.clone();
        let n = (frame.len() - 4 - 6) as u16;
        short[2..4].copy_from_slice(&n.to_le_bytes());
        server.send_to(&short, data).await.unwrap();
        // A labeled-marker count that would overflow the packet.
        let mut big = frame.clone();
        // frame number, 4 empty section counts, then the labeled count.
        big[4 + 20..4 + 24].copy_from_slice(&i32::MAX.to_le_bytes());
        server.send_to(&big, data).await.unwrap();
        // An unknown message id.
        server.send_to(&[77, 0, 2, 0, 1, 2], data).await.unwrap();
        // A SERVERINFO on the data channel (Motive 1.x does this).
        server
            .send_to(
                &encode(&Packet::ServerInfo(info), Version::new(2, 9)).unwrap(),
                data,
            )
            .await
            .unwrap();
        // Good frames afterwards.
        for k in 2..5 {
            server.send_to(&good_frame(k), data).await.unwrap();
        }
        let mut got = Vec::new();
        for _ in 0..200 {
            got.extend(rx.try_iter());
            if got.len() >= 3 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let _ = stop.send(true);
        client.await.unwrap().unwrap();
        assert_eq!(
            got.iter().map(|f| f.frame).collect::<Vec<_>>(),
            vec![2, 3, 4]
        );
        assert_eq!(got[0].markers[0].position.y, 1.5);
        assert_eq!(stats.incomplete.load(Ordering::Relaxed), 2);
        assert_eq!(stats.invalid.load(Ordering::Relaxed), 1);
        assert_eq!(stats.unknown.load(Ordering::Relaxed), 1);
        assert_eq!(stats.skipped.load(Ordering::Relaxed), 1);
        assert_eq!(stats.frames.load(Ordering::Relaxed), 3);
    });
}
