//! TOML scene files: a scene file and its OBJ give the same scene, `export` round-trips,
//! transforms and material overrides do what the README says, flags override the file, and
//! degenerate geometry is dropped with a counted warning.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::BuildSettings,
    load,
    scene::{local_frame::point_to_world, Scene},
    settings::scene::SceneSettings,
    Loaded,
};
use paths::{mesh, repo};
use shared::{
    glam::{DVec3, Vec3, Vec4},
    triangle::geometric_normal,
    vecmath::xyz,
};
use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

fn tmp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-scene-{}", std::process::id())).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn kdtrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(args).output().expect("run kdtrace")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn loaded(p: &Path) -> Loaded {
    load(p, BuildSettings::default()).unwrap_or_else(|e| panic!("{}: {e:#}", p.display()))
}

fn assert_same_scene(a: &Scene, b: &Scene, what: &str) {
    let tri = |s: &Scene| bytemuck::cast_slice::<_, u8>(&s.triangles).to_vec();
    let mat = |s: &Scene| bytemuck::cast_slice::<_, u8>(&s.materials).to_vec();
    let light = |s: &Scene| bytemuck::cast_slice::<_, u8>(&s.lights).to_vec();
    assert!(tri(a) == tri(b), "{what}: triangles differ");
    assert_eq!(a.info, b.info, "{what}: triangle info differs");
    assert!(mat(a) == mat(b), "{what}: materials differ");
    assert!(light(a) == light(b), "{what}: lights differ");
}

fn resolved(l: &Loaded) -> kdtrace::settings::RenderSettings {
    let (lo, hi) = l.compiled.world_bounds();
    l.settings.resolve(lo, hi).unwrap()
}

/// Every scene file in scenes/.
fn scene_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 4, "scenes/ should hold the Cornell box and the test meshes' scene files: {v:?}");
    v
}

#[test]
fn the_cornell_scene_file_is_the_cornell_obj_with_its_camera() {
    let toml = loaded(&repo("scenes/cornell-box.toml"));
    let obj = loaded(&repo("scenes/cornell-box.obj"));
    assert_same_scene(&toml.compiled.scene, &obj.compiled.scene, "cornell-box.toml vs .obj");
    let s = resolved(&toml);
    assert_eq!(s.camera.eye, DVec3::new(0.278, 0.273, 0.8));
    assert_eq!((s.width, s.height, s.spp, s.max_bounces), (512, 512, 64, 6));
    assert_eq!(obj.settings, SceneSettings::default());
}

#[test]
fn every_scene_file_loads_and_export_round_trips() {
    for (i, src) in scene_files().into_iter().enumerate() {
        let dir = tmp_dir(&format!("export-{i}"));
        let first = dir.join("first.toml");
        let o = kdtrace(&["export", src.to_str().unwrap(), "--out", first.to_str().unwrap()]);
        assert!(o.status.success(), "{}: {}", src.display(), stderr(&o));
        let (a, b) = (loaded(&src), loaded(&first));
        assert_same_scene(&a.compiled.scene, &b.compiled.scene, &src.display().to_string());
        let (sa, sb) = (resolved(&a), resolved(&b));
        assert_eq!(
            (sa.camera, sa.width, sa.height, sa.spp, sa.max_bounces, sa.seed, sa.environment),
            (sb.camera, sb.width, sb.height, sb.spp, sb.max_bounces, sb.seed, sb.environment),
            "{}",
            src.display()
        );
        assert_eq!(a.settings.time_limit_s, b.settings.time_limit_s);
        // Exporting the export, from another folder, gives the same file bar the comment.
        let second = tmp_dir(&format!("export-{i}/deeper")).join("second.toml");
        assert!(kdtrace(&["export", first.to_str().unwrap(), "--out", second.to_str().unwrap()]).status.success());
        let body = |p: &Path| {
            std::fs::read_to_string(p)
                .unwrap()
                .lines()
                .filter(|l| !l.starts_with('#') && !l.starts_with("file"))
                .collect::<Vec<_>>()
                .join("\n")
        };
        assert_eq!(body(&first), body(&second), "{}: export is not a fixed point", src.display());
        assert_same_scene(&a.compiled.scene, &loaded(&second).compiled.scene, "second export");
    }
}

#[test]
fn an_obj_exports_to_a_scene_file_with_its_default_camera() {
    let src = mesh("CornellBox-Original/CornellBox-Original.obj");
    let out = tmp_dir("export-obj").join("original.toml");
    let o = kdtrace(&["export", src.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (loaded(&src), loaded(&out));
    assert_same_scene(&a.compiled.scene, &b.compiled.scene, "CornellBox-Original");
    assert_eq!(resolved(&a).camera, resolved(&b).camera);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("CornellBox-Original/CornellBox-Original.obj"), "{text}");
}

fn one_triangle_obj(dir: &Path) {
    std::fs::write(dir.join("tri.mtl"), "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\nnewmtl wall\nKd 0.2 0.2 0.2\n")
        .unwrap();
    std::fs::write(
        dir.join("tri.obj"),
        "mtllib tri.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\nusemtl wall\nf 1 3 2\n",
    )
    .unwrap();
}

#[test]
fn transforms_apply_scale_then_rotate_then_translate() {
    let dir = tmp_dir("transform");
    one_triangle_obj(&dir);
    let scene = dir.join("t.toml");
    std::fs::write(
        &scene,
        "[[mesh]]\nfile = \"tri.obj\"\nscale = [2, 1, 1]\nrotate = [0, 0, 90]\ntranslate = [0, 0, 5]\n",
    )
    .unwrap();
    let l = loaded(&scene);
    let t = l.compiled.scene.triangles[0];
    // The loaded scene is stored relative to its origin (`local_frame`): here z = 5 on every
    // vertex, so z moves to 0 and the origin holds the 5.
    let origin = l.compiled.origin;
    assert_eq!(origin, DVec3::new(0.0, 0.0, 5.0));
    let xyz = |v: Vec4| point_to_world(v.truncate(), origin);
    // (1,0,0) → ×2 → (2,0,0) → 90° about z → (0,2,0) → +5 z → (0,2,5); (0,1,0) → (−1,0,5).
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-5;
    assert!(close(xyz(t.v0), DVec3::new(0.0, 0.0, 5.0)), "{t:?}");
    assert!(close(xyz(t.v1), DVec3::new(0.0, 2.0, 5.0)), "{t:?}");
    assert!(close(xyz(t.v2), DVec3::new(-1.0, 0.0, 5.0)), "{t:?}");
    // Uniform scale, and rotation about x before y: (0,1,0) → x 90° → (0,0,1) → y 90° → (1,0,0).
    std::fs::write(&scene, "[[mesh]]\nfile = \"tri.obj\"\nscale = 3\nrotate = [90, 90, 0]\n").unwrap();
    let l = loaded(&scene);
    let t = l.compiled.scene.triangles[0];
    assert!(close(point_to_world(t.v2.truncate(), l.compiled.origin), DVec3::new(3.0, 0.0, 0.0)), "{t:?}");
}

#[test]
fn a_mirroring_transform_keeps_the_emitting_side_mirrored() {
    let dir = tmp_dir("mirror");
    one_triangle_obj(&dir);
    let scene = dir.join("m.toml");
    let normal_of_light = |text: &str| {
        std::fs::write(&scene, text).unwrap();
        let l = loaded(&scene);
        let s = &l.compiled.scene;
        assert_eq!(s.lights.len(), 1);
        geometric_normal(&s.triangles[s.lights[0].triangle as usize]).normalize()
    };
    let plain = normal_of_light("[[mesh]]\nfile = \"tri.obj\"\n");
    assert!(plain.z > 0.99, "{plain}");
    // Mirrored in z: the lamp faced +z, its mirror image faces −z.
    let mirrored = normal_of_light("[[mesh]]\nfile = \"tri.obj\"\nscale = [1, 1, -1]\n");
    assert!(mirrored.z < -0.99, "{mirrored}");
    // Mirrored in x: still faces +z.
    let side = normal_of_light("[[mesh]]\nfile = \"tri.obj\"\nscale = [-2, 1, 1]\n");
    assert!(side.z > 0.99, "{side}");
}

#[test]
fn material_overrides_by_mtl_name_and_for_the_whole_mesh() {
    let dir = tmp_dir("override");
    std::fs::copy(repo("scenes/cornell-box.obj"), dir.join("cornell-box.obj")).unwrap();
    std::fs::copy(repo("scenes/cornell-box.mtl"), dir.join("cornell-box.mtl")).unwrap();
    let scene = dir.join("o.toml");
    std::fs::write(
        &scene,
        "[materials.blue]\nalbedo = [0.1, 0.2, 0.9]\n[materials.grey]\nalbedo = [0.5, 0.5, 0.5]\n[materials.sun]\ntype = \"diffuse\"\nemission = [3, 3, 3]\n\
         [[mesh]]\nfile = \"cornell-box.obj\"\nmaterials = { red = \"blue\", light = \"sun\" }\n",
    )
    .unwrap();
    let obj = loaded(&dir.join("cornell-box.obj"));
    let l = loaded(&scene);
    let (s, o) = (&l.compiled.scene, &obj.compiled.scene);
    assert_eq!(s.triangles.len(), o.triangles.len());
    let name = |sc: &Scene, i: usize| sc.material_names[sc.info[i].material as usize].clone();
    for i in 0..s.triangles.len() {
        let expected = match name(o, i).as_str() {
            "red" => "blue".to_string(),
            "light" => "sun".to_string(),
            other => other.to_string(),
        };
        assert_eq!(name(s, i), expected, "triangle {i}");
    }
    let sun = s.materials[s.material_names.iter().position(|n| n == "sun").unwrap()];
    assert_eq!(xyz(sun.emission), Vec3::splat(3.0));
    assert_eq!(s.lights.len(), 2);
    // A whole-mesh override: every face grey, so no light is left.
    std::fs::write(
        &scene,
        "[materials.grey]\nalbedo = [0.5, 0.5, 0.5]\n[[mesh]]\nfile = \"cornell-box.obj\"\nmaterial = \"grey\"\n",
    )
    .unwrap();
    let l = loaded(&scene);
    assert!(l.compiled.scene.info.iter().all(|t| l.compiled.scene.material_names[t.material as usize] == "grey"));
    assert!(l.compiled.scene.lights.is_empty());
    // Per-name wins over whole-mesh.
    std::fs::write(&scene, "[materials.grey]\n[materials.sun]\nemission = [1, 1, 1]\n[[mesh]]\nfile = \"cornell-box.obj\"\nmaterial = \"grey\"\nmaterials = { light = \"sun\" }\n").unwrap();
    assert_eq!(loaded(&scene).compiled.scene.lights.len(), 2);
}

#[test]
fn flags_override_the_scene_file_which_overrides_the_defaults() {
    let dir = tmp_dir("flags");
    let scene = dir.join("f.toml");
    std::fs::write(
        &scene,
        format!("environment = [0.2, 0.2, 0.2]\n[camera]\nwidth = 20\nheight = 10\n[render]\nspp = 2\nbounces = 1\nseed = 7\ntime_limit = 30\n[[mesh]]\nfile = {:?}\n", repo("scenes/cornell-box.obj").to_str().unwrap()),
    )
    .unwrap();
    let out = dir.join("f.png");
    let run = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["render", scene.to_str().unwrap(), "--out", out.to_str().unwrap(), "--json"];
        args.extend_from_slice(extra);
        let o = kdtrace(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let j = run(&[]);
    assert_eq!(
        (j["width"].as_u64(), j["height"].as_u64(), j["spp"].as_u64(), j["bounces"].as_u64(), j["seed"].as_u64()),
        (Some(20), Some(10), Some(2), Some(1), Some(7))
    );
    let j = run(&["--spp", "3", "--width", "8", "--seed", "1"]);
    assert_eq!(
        (j["width"].as_u64(), j["height"].as_u64(), j["spp"].as_u64(), j["bounces"].as_u64(), j["seed"].as_u64()),
        (Some(8), Some(10), Some(3), Some(1), Some(1))
    );
    // The environment reaches the renderer: looking away from the box sees it.
    let exr = dir.join("env.exr");
    let o = kdtrace(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        exr.to_str().unwrap(),
        "--eye",
        "0,0,5",
        "--target",
        "0,0,10",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, px) = kdtrace::image::io::read_exr(&exr).unwrap();
    assert!(px.iter().all(|p| (p[0] - 0.2).abs() < 1e-6), "environment not seen: {:?}", px[0]);
    let l = loaded(&scene);
    assert_eq!(l.settings.time_limit_s, Some(30.0));
}

#[test]
fn degenerate_geometry_is_dropped_with_a_counted_warning() {
    let dir = tmp_dir("degenerate");
    let obj = dir.join("d.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\np 1 2\nl 1 2 3\nf 1 2\n")
        .unwrap();
    let out = dir.join("d.png");
    let o = kdtrace(&[
        "render",
        obj.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--spp",
        "1",
        "--width",
        "4",
        "--height",
        "4",
        "--json",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("d.obj: 2 zero-area triangles dropped"), "{err}");
    assert!(err.contains("d.obj: 4 point and line elements skipped"), "{err}");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((j["triangles"].as_u64(), j["dropped_degenerate"].as_u64()), (Some(1), Some(2)));
}
