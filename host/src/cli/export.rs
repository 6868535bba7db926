//! `kdtrace export`: a scene (.obj, .gltf, .glb or .toml) as a TOML scene file that states every setting.
use super::load;
use crate::files;
use crate::kdbuild::BuildSettings;
use crate::scene::file;
use crate::settings::SceneSettings;
use crate::SceneKind;
use anyhow::{anyhow, bail, Result};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args)]
pub struct ExportArgs {
    scene: PathBuf,
    /// The TOML scene file to write (mesh paths are written relative to it).
    #[arg(long)]
    out: PathBuf,
    /// glTF scenes: the camera the scene file states, by index or name (default: the first).
    #[arg(long, value_name = "NAME|INDEX")]
    camera: Option<String>,
}

pub fn run(e: ExportArgs) -> Result<ExitCode> {
    if SceneKind::of(&e.out).ok() != Some(SceneKind::Toml) {
        bail!("{}: export writes a .toml scene file", e.out.display());
    }
    files::check_outputs(&[&e.out], &[&e.scene])?;
    let scene_file = match SceneKind::of(&e.scene)? {
        SceneKind::Kdc => bail!(
            "{}: a compiled scene keeps no mesh files and cannot be exported; export the scene it was compiled from",
            e.scene.display()
        ),
        SceneKind::Obj | SceneKind::Gltf => file::for_obj(&e.scene),
        SceneKind::Toml => {
            let bytes = files::read_input(&e.scene, files::MAX_TEXT_BYTES)
                .map_err(|err| anyhow!("{}: cannot read: {err}", e.scene.display()))?;
            let text = std::str::from_utf8(files::without_bom(&bytes))
                .map_err(|err| anyhow!("{}: not UTF-8 text (byte {})", e.scene.display(), err.valid_up_to()))?;
            file::parse(&e.scene, text)?
        }
    };
    // Loading checks every mesh and resolves the camera framing that the file may leave open.
    let loaded = load(&e.scene, BuildSettings::default(), e.camera.as_deref())?;
    let c = &loaded.compiled;
    let (lo, hi) = c.world_bounds();
    let resolved = loaded.settings.resolve(lo, hi)?;
    let pinned = SceneSettings::pinned(&resolved, loaded.settings.time_limit_s);
    let mut scene_file = file::with_settings(scene_file, &pinned)?;
    file::rebase_meshes(&mut scene_file, &e.scene, &e.out)?;
    let comment = format!(
        "kdtrace scene file, written by `kdtrace export` from {}.\nSchema: README.md, \"Scene files\".",
        e.scene.display()
    );
    let text = file::to_toml(&scene_file, &comment)?;
    files::write_bytes(&e.out, text.as_bytes())?;
    eprintln!("{}: {} meshes, {} triangles", e.out.display(), scene_file.meshes.len(), c.scene.triangles.len());
    Ok(ExitCode::SUCCESS)
}
