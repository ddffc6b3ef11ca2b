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
use crate::error::Result;
use crate::reconstruct::forest::{self, ForestCache};
use crate::render::forest::{forest_model, forest_picture};
use crate::render::outputs::{Motion, Outputs};
use crate::serve::http;
use crate::serve::osc::{tree_datagrams, OscSender};
use crate::serve::snapshot::{SnapshotNode, SnapshotTree, TreeSnapshot};

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
    // The last forest: only the trees whose inputs changed are grown again.
    let mut cache = ForestCache::default();
    while let Some(request) = shared.requests.take() {
        let started = Instant::now();
        let animate = lock(&shared.recon_config).animate.clone();
        let outputs = match build_forest(shared, &request, &mut cache) {
            Ok(o) => o,
            Err(e) => {
                tracing::error!("reconstruction: {e}");
                shared.output_error(Some(format!("reconstruction: {e}")));
                continue;
            }
        };
        // How the tree sways with the live tips (daemon::pose); several
        // trees each have their own rig (snapshot_trees).
        let rig = if outputs.report.forest.is_none() {
            Rig::new(&outputs.tree, &animate).ok().map(Arc::new)
        } else {
            None
        };
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

/// The trees of a request (one, or several: docs/forest.md), grown where
/// their inputs changed since the last request.
fn build_forest(
    shared: &Shared,
    request: &TreeRequest,
    cache: &mut ForestCache,
) -> Result<Outputs> {
    let config = lock(&shared.recon_config).clone();
    let plan = forest::plan(
        &request.tips,
        &request.links,
        &config.trees,
        &config.forest,
        &config.reconstruct,
    )?;
    forest_model(
        &plan,
        request.wind,
        &config.reconstruct,
        Motion::Rigged,
        Some(cache),
    )
}

/// Every tree of several as the snapshot carries it (none for a tree
/// alone): skeleton and its own version-1 tree.json.
fn snapshot_trees(shared: &Shared, outputs: &Outputs) -> Vec<SnapshotTree> {
    let Some(report) = &outputs.report.forest else {
        return Vec::new();
    };
    let (settings, animate) = {
        let c = lock(&shared.recon_config);
        (c.reconstruct.clone(), c.animate.clone())
    };
    outputs
        .trees
        .iter()
        .zip(&report.trees)
        .map(|(m, line)| SnapshotTree {
            id: m.id,
            name: m.name.clone(),
            base: m.base.to_array(),
            tips: line.tips,
            rebuilt: m.rebuilt,
            nodes: SnapshotNode::of_tree(&m.tree),
            tree_json: crate::render::json::to_json_seeded(&m.tree, &settings, m.seed)
                .unwrap_or_default(),
            rig: Rig::new(&m.tree, &animate).ok().map(Arc::new),
        })
        .collect()
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
    let trees = snapshot_trees(shared, &outputs);
    let snapshot = Arc::new(TreeSnapshot {
        version,
        time_s: request.time_s,
        reason: request.reason.to_string(),
        nodes: SnapshotNode::of_tree(&outputs.tree),
        glb: outputs.glb,
        tree_json: outputs.tree_json,
        tips_json: request.tips_json,
        trees,
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
    let png = forest_picture(
        &outputs.tree,
        &outputs.trees,
        outputs.report.forest.is_some(),
        None,
    )
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
        "trees": outputs.trees.len().max(1),
        "trees_rebuilt": outputs.trees.iter().filter(|m| m.rebuilt).count().max(1),
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
