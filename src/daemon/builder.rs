//! The tree builder thread: takes the latest tree request, runs the particle
//! flow, and hands the tree to every output — viewers first (memory and
//! sockets), then OSC, the picture and the files.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

use crossbeam_channel::Sender;
use glam::DVec3;

use super::shared::{lock, Shared, TreeRequest};
use crate::animate::Rig;
use crate::app::files::write_atomic;
use crate::render::outputs::{build_model, Motion, Outputs};
use crate::serve::http;
use crate::serve::osc::{tree_datagrams, OscSender};
use crate::serve::snapshot::{SnapshotNode, TreeSnapshot};

/// Builds trees until the analysis closes the requests.
pub(crate) fn run(shared: &Arc<Shared>, tips_tx: Sender<Vec<(usize, DVec3)>>) {
    let mut version = 0;
    let mut osc = match super::osc_sender(&shared.config.daemon.osc_targets) {
        Ok(o) => o,
        Err(e) => {
            tracing::error!("OSC out: {e}");
            shared.output_error(Some(format!("OSC out: {e}")));
            None
        }
    };
    while let Some(request) = shared.requests.take() {
        let started = Instant::now();
        let (settings, animate) = {
            let c = lock(&shared.recon_config);
            (c.reconstruct.clone(), c.animate.clone())
        };
        let outputs = match build_model(&request.tips, request.wind, &settings, Motion::Rigged) {
            Ok(o) => o,
            Err(e) => {
                tracing::error!("reconstruction: {e}");
                shared.output_error(Some(format!("reconstruction: {e}")));
                continue;
            }
        };
        // How the tree sways with the live tips (daemon::pose).
        let rig = Rig::new(&outputs.tree, &animate).ok().map(Arc::new);
        version += 1;
        publish(
            shared,
            request,
            (outputs, rig),
            version,
            started,
            &tips_tx,
            osc.as_mut(),
        );
    }
}

fn publish(
    shared: &Shared,
    request: TreeRequest,
    (outputs, rig): (Outputs, Option<Arc<Rig>>),
    version: u64,
    started: Instant,
    tips_tx: &Sender<Vec<(usize, DVec3)>>,
    osc: Option<&mut OscSender>,
) {
    let snapshot = Arc::new(TreeSnapshot {
        version,
        time_s: request.time_s,
        reason: request.reason.to_string(),
        nodes: SnapshotNode::of_tree(&outputs.tree),
        glb: outputs.glb,
        tree_json: outputs.tree_json,
        tips_json: request.tips_json,
        rig,
    });
    let _ = shared.tree_tx.send(Some(snapshot.clone()));
    let tips = request
        .tips
        .iter()
        .map(|t| (t.marker, t.position))
        .collect();
    let _ = tips_tx.try_send(tips);
    shared.hub.publish_event(http::tree_notice(&snapshot));
    let published_ms = request.fired.elapsed().as_secs_f64() * 1000.0;
    if let Some(o) = osc {
        o.send_paced(&tree_datagrams(&snapshot));
    }
    // A picture that cannot be drawn is reported, and no empty tree.png is
    // written in its place.
    let png = crate::render::picture::tree_png(&outputs.tree, None)
        .map_err(|e| tracing::error!("tree.png: {e}"))
        .ok();
    write_files(shared, &snapshot, png.as_deref(), version);
    let st = &shared.status;
    st.trees.fetch_add(1, Ordering::Relaxed);
    st.tree_version.store(version, Ordering::Relaxed);
    *lock(&st.last_tree) = Some(serde_json::json!({
        "version": version,
        "reason": request.reason,
        "reason_text": request.reason.to_string(),
        "time_s": request.time_s,
        "nodes": snapshot.nodes.len(),
        "tips": request.tips.len(),
        "forced_joins": outputs.report.forced_joins,
        "trigger_to_outputs_ms": published_ms,
        "build_ms": started.elapsed().as_secs_f64() * 1000.0,
    }));
}

/// Rewrites tree.glb, tree.json, tips.json, tree.png (and the numbered
/// history). A failing disk is reported on /status; the daemon goes on.
fn write_files(shared: &Shared, t: &TreeSnapshot, png: Option<&[u8]>, version: u64) {
    let mut files: Vec<(String, &[u8])> = vec![
        ("tree.glb".into(), &t.glb),
        ("tree.json".into(), t.tree_json.as_bytes()),
        ("tips.json".into(), t.tips_json.as_bytes()),
    ];
    let mut error = None;
    match png {
        Some(png) => files.push(("tree.png".into(), png)),
        None => error = Some("tree.png: the picture could not be drawn".to_string()),
    }
    if shared.config.daemon.history {
        files.push((format!("tree-{version:04}.glb"), &t.glb));
        files.push((format!("tree-{version:04}.json"), t.tree_json.as_bytes()));
    }
    for (name, bytes) in files {
        if let Err(e) = write_atomic(&shared.out.join(&name), bytes) {
            tracing::error!("{e}");
            error = Some(e.to_string());
        }
    }
    shared.output_error(error);
}
