//! `kdtrace tree`: build a scene's k-d tree, report its statistics, optionally validate it.
use super::args::BuildArgs;
use super::print_json;
use crate::kdbuild::{stats, validate, BuildSettings, Builder, TreeStats};
use anyhow::Result;
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args)]
pub struct TreeArgs {
    scene: PathBuf,
    #[command(flatten)]
    build: BuildArgs,
    /// Check every invariant of the tree (slow on big scenes).
    #[arg(long)]
    validate: bool,
    /// Print one JSON line instead of text.
    #[arg(long)]
    json: bool,
}

/// `tree --json`: the statistics and how they were made.
#[derive(Serialize)]
struct TreeReport<'a> {
    #[serde(flatten)]
    stats: &'a TreeStats,
    scene: &'a PathBuf,
    builder: Builder,
    settings: BuildSettings,
    threads: usize,
    load_s: f64,
    build_s: f64,
    prepare_s: f64,
    mtris_per_s: f64,
    /// With `--validate`: whether every invariant holds, and the first that does not.
    valid: Option<bool>,
    invalid_reason: Option<&'a str>,
}

pub fn run(t: TreeArgs) -> Result<ExitCode> {
    let settings = t.build.settings()?;
    let loaded = crate::load(&t.scene, settings)?;
    let c = &loaded.compiled;
    let st = stats(c.tree(), c.scene.triangles.len(), &settings);
    let valid = t.validate.then(|| validate(c.tree(), &c.scene.triangles));
    let mtris_per_s = st.triangles as f64 / loaded.build_s / 1e6;
    if t.json {
        print_json(&TreeReport {
            stats: &st,
            scene: &t.scene,
            builder: settings.builder,
            settings,
            threads: rayon::current_num_threads(),
            load_s: loaded.load_s,
            build_s: loaded.build_s,
            prepare_s: loaded.prepare_s,
            mtris_per_s,
            valid: valid.as_ref().map(|v| v.is_ok()),
            invalid_reason: valid.as_ref().and_then(|v| v.as_ref().err()).map(String::as_str),
        })?;
    } else {
        outln!(
            "{}: {} triangles, {:?} tree: {} nodes, {} leaves ({} empty), depth {}, {} refs ({:.2} per non-empty \
             leaf), SAH cost {:.2}; built in {:.3} s on {} threads ({mtris_per_s:.2} Mtris/s)",
            t.scene.display(),
            st.triangles,
            settings.builder,
            st.nodes,
            st.leaves,
            st.empty_leaves,
            st.max_depth,
            st.total_refs,
            st.mean_leaf_refs,
            st.sah_cost,
            loaded.build_s,
            rayon::current_num_threads(),
        )?;
        match &valid {
            Some(Ok(())) => outln!("valid")?,
            Some(Err(e)) => outln!("INVALID: {e}")?,
            None => {}
        }
    }
    Ok(if valid.is_some_and(|v| v.is_err()) { ExitCode::from(1) } else { ExitCode::SUCCESS })
}
