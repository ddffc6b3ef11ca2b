//! `treemocap view`: a finished session on the live page, with a timeline.
//!
//! [`SessionFrames`] holds every frame of the recording with what the marker
//! stage made of it: each tip's sample (measured, filled across a gap, or
//! missing: shown at its last known position as not seen), and which raw
//! markers no tip claims (noise). The page asks for one frame at a time
//! (`GET /frame/N`, the binary frame of `/live`) while the user scrubs.

use std::collections::HashMap;
use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use glam::DVec3;

use crate::model::frame::MarkerFrame;
use crate::model::tips::Tips;
use crate::model::trace::SampleKind;
use crate::protocol::live_frame::{self, LiveFrame, LiveTip, MarkerClass, TipState};

/// A tip marker and a raw marker closer than this are the same marker: the
/// traces store positions quantized to 0.01 mm (`model::trace::QUANTUM_M`).
const SAME_MARKER_M: f32 = 5e-5;

/// One tip over the whole session, one entry per internal frame.
#[derive(Debug)]
struct TipTrack {
    marker: u32,
    /// Measured, filled or not seen, per frame.
    states: Vec<TipState>,
    /// Position per frame (the last known one where not seen).
    positions: Vec<[f32; 3]>,
}

/// Every frame of a session, ready to send (12 bytes per marker sample and
/// 16 per tip and frame are kept in memory).
#[derive(Debug, Default)]
pub struct SessionFrames {
    /// Source frame number per internal frame.
    numbers: Vec<i64>,
    /// Time (s) per internal frame.
    times: Vec<f64>,
    /// Raw markers per internal frame (empty where the recording skipped one).
    markers: Vec<Vec<[f32; 3]>>,
    tips: Vec<TipTrack>,
    frame_rate: f64,
}

fn f32x3(p: DVec3) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

impl SessionFrames {
    /// The session from its frames (in recorded order) and the marker
    /// stage's result on the same recording.
    pub fn new(frames: Vec<MarkerFrame>, tips: &Tips) -> Self {
        let n = tips.timeline.len();
        let by_number: HashMap<i64, usize> = frames
            .iter()
            .enumerate()
            .map(|(i, f)| (f.frame, i))
            .collect();
        let numbers: Vec<i64> = (0..n as i64)
            .map(|t| tips.timeline.source_frame(t).unwrap_or(t))
            .collect();
        let markers = numbers
            .iter()
            .map(|num| {
                by_number
                    .get(num)
                    .map(|&i| frames[i].positions().map(f32x3).collect())
                    .unwrap_or_default()
            })
            .collect();
        let tracks = tips
            .tips
            .iter()
            .map(|tip| {
                let mut states = vec![TipState::Unseen; n];
                let mut positions = vec![f32x3(tip.rest); n];
                let mut last = f32x3(tip.rest);
                let mut next = 0usize;
                for s in tip.trace.samples() {
                    let Ok(t) = usize::try_from(s.frame) else {
                        continue;
                    };
                    if t >= n {
                        break;
                    }
                    // Frames before this sample hold the last known position.
                    for p in positions.iter_mut().take(t).skip(next) {
                        *p = last;
                    }
                    match s.kind {
                        SampleKind::Measured => states[t] = TipState::Measured,
                        SampleKind::Filled => states[t] = TipState::Filled,
                        SampleKind::Missing => {}
                    }
                    if s.kind != SampleKind::Missing {
                        last = f32x3(s.position);
                    }
                    positions[t] = last;
                    next = t + 1;
                }
                for p in positions.iter_mut().skip(next) {
                    *p = last;
                }
                TipTrack {
                    marker: tip.marker as u32,
                    states,
                    positions,
                }
            })
            .collect();
        SessionFrames {
            numbers,
            times: tips.timeline.times.clone(),
            markers,
            tips: tracks,
            frame_rate: tips.frame_rate,
        }
    }

    /// Internal frames in the session.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True for a session without frames.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Frame `t` (0-based, internal) as the page draws it.
    pub fn frame(&self, t: usize) -> Option<LiveFrame> {
        let markers = self.markers.get(t)?.clone();
        let tips: Vec<LiveTip> = self
            .tips
            .iter()
            .map(|k| LiveTip {
                marker: k.marker,
                state: k.states[t],
                position: k.positions[t],
            })
            .collect();
        let classes = if tips.is_empty() {
            Vec::new()
        } else {
            markers
                .iter()
                .map(|m| {
                    let claimed = tips.iter().any(|tip| {
                        tip.state == TipState::Measured
                            && (0..3).all(|k| (tip.position[k] - m[k]).abs() <= SAME_MARKER_M)
                    });
                    if claimed {
                        MarkerClass::Tip
                    } else {
                        MarkerClass::Noise
                    }
                })
                .collect()
        };
        Some(LiveFrame {
            frame: self.numbers[t],
            time_s: self.times[t],
            markers,
            classes,
            tips,
        })
    }

    /// `session.json`: what the timeline needs.
    pub fn info(&self, source: &str, tree: bool) -> serde_json::Value {
        let first = self.times.first().copied().unwrap_or(0.0);
        let last = self.times.last().copied().unwrap_or(0.0);
        serde_json::json!({
            "source": source,
            "frames": self.len(),
            "frame_rate_hz": self.frame_rate,
            "first_frame": self.numbers.first(),
            "duration_s": last - first,
            "tips": self.tips.len(),
            "tree": tree,
        })
    }
}

/// What the view routes read.
#[derive(Clone)]
pub struct ViewState {
    /// The frames.
    pub frames: Arc<SessionFrames>,
    /// `session.json`, made once.
    pub info: Arc<serde_json::Value>,
}

/// `GET /session.json` and `GET /frame/{n}`.
pub fn routes(state: ViewState) -> Router {
    Router::new()
        .route("/session.json", get(session))
        .route("/frame/{n}", get(frame))
        .with_state(state)
}

async fn session(State(s): State<ViewState>) -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        s.info.to_string(),
    )
        .into_response()
}

async fn frame(State(s): State<ViewState>, Path(n): Path<usize>) -> Response {
    match s.frames.frame(n) {
        Some(f) => (
            [(header::CONTENT_TYPE, "application/octet-stream")],
            live_frame::encode(&f),
        )
            .into_response(),
        None => (
            StatusCode::NOT_FOUND,
            format!("no frame {n}: the session has {} frames\n", s.frames.len()),
        )
            .into_response(),
    }
}
