//! A table of broken inputs, each run through the CLI: the exit code must be 2 (input error,
//! never 101, a panic) and the message must name the file, the line and column where they apply,
//! and the problem. OBJ/MTL, TOML scene files, `.kdc` compiled scenes and command-line values.
#[path = "common/kdc_craft.rs"]
mod craft;

use kdtrace::{kdbuild::BuildSettings, render::kdc};
use std::{
    path::{Path, PathBuf},
    process::Command,
};

fn repo(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(rel).to_string_lossy().into_owned()
}

/// One broken input: the files to write (name, bytes) in a fresh folder, the command (`{dir}` is
/// that folder), and what stderr must contain.
struct Case {
    name: &'static str,
    files: Vec<(&'static str, Vec<u8>)>,
    args: Vec<String>,
    needles: Vec<String>,
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

fn render(scene: &str) -> Vec<String> {
    render_args(&format!("{{dir}}/{scene}"))
}

/// `render SCENE` of a tiny image at one sample.
fn render_args(scene: &str) -> Vec<String> {
    vec![
        "render".into(),
        scene.to_string(),
        "--out".into(),
        "{dir}/never.png".into(),
        "--spp".into(),
        "1".into(),
        "--width".into(),
        "4".into(),
        "--height".into(),
        "4".into(),
    ]
}

fn case(name: &'static str, files: Vec<(&'static str, &str)>, args: Vec<String>, needles: &[&str]) -> Case {
    Case {
        name,
        files: files.into_iter().map(|(n, t)| (n, t.as_bytes().to_vec())).collect(),
        args,
        needles: needles.iter().map(|s| s.to_string()).collect(),
    }
}

/// A scene file `s.toml` beside a good one-triangle `m.obj`.
fn toml_case(name: &'static str, toml: &str, needles: &[&str]) -> Case {
    case(name, vec![("s.toml", toml), ("m.obj", &format!("{TRI}f 1 2 3\n"))], render("s.toml"), needles)
}

fn kdc_case(name: &'static str, bytes: Vec<u8>, needles: &[&str]) -> Case {
    Case {
        name,
        files: vec![("c.kdc", bytes)],
        args: render("c.kdc"),
        needles: needles.iter().map(|s| s.to_string()).collect(),
    }
}

fn cases() -> Vec<Case> {
    let cornell = kdtrace::load(Path::new(&repo("scenes/cornell-box.toml")), BuildSettings::default()).unwrap();
    let good = kdc::encode(&cornell.compiled, &BuildSettings::default(), &cornell.settings).unwrap();
    let crafted = |edit: &dyn Fn(&mut craft::Parts)| {
        let mut p = craft::split(&good);
        edit(&mut p);
        craft::join(&p)
    };
    let mesh = "[[mesh]]\nfile = \"m.obj\"\n";
    vec![
        // ---- OBJ and MTL ----
        case("missing OBJ", vec![], render("absent.obj"), &["absent.obj", "cannot read"]),
        case(
            "NaN coordinate",
            vec![("a.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n")],
            render("a.obj"),
            &["a.obj:3", "not finite"],
        ),
        case(
            "1e39 coordinate",
            vec![("a.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n")],
            render("a.obj"),
            &["a.obj:2", "1e39"],
        ),
        case(
            "inf coordinate",
            vec![("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 -inf\nf 1 2 3\n")],
            render("a.obj"),
            &["a.obj:3"],
        ),
        case(
            "vertex with two coordinates",
            vec![("a.obj", "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")],
            render("a.obj"),
            &["a.obj:1", "3 coordinates"],
        ),
        case(
            "vertex that is not a number",
            vec![("a.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n")],
            render("a.obj"),
            &["a.obj:2", "not a number"],
        ),
        case("no faces", vec![("a.obj", TRI)], render("a.obj"), &["a.obj", "no triangles"]),
        case(
            "face index beyond the vertices",
            vec![("a.obj", &format!("{TRI}f 1 2 9\n"))],
            render("a.obj"),
            &["a.obj:4", "index 9 out of range"],
        ),
        case(
            "negative face index beyond the vertices",
            vec![("a.obj", &format!("{TRI}f -1 -2 -7\n"))],
            render("a.obj"),
            &["a.obj:4", "index -7 out of range"],
        ),
        case("face index zero", vec![("a.obj", &format!("{TRI}f 0 1 2\n"))], render("a.obj"), &["a.obj:4", "index 0"]),
        case(
            "MTL with NaN Kd",
            vec![("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")), ("a.mtl", "newmtl x\nKd nan 0 0\n")],
            render("a.obj"),
            &["a.mtl", "\"x\"", "Kd"],
        ),
        case(
            "MTL with negative Ke",
            vec![("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")), ("a.mtl", "newmtl x\nKe -1 0 0\n")],
            render("a.obj"),
            &["a.mtl", "Ke"],
        ),
        case(
            "MTL with 1e39 Ke",
            vec![("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")), ("a.mtl", "newmtl x\nKe 1e39 0 0\n")],
            render("a.obj"),
            &["a.mtl", "Ke"],
        ),
        case(
            "MTL that does not parse",
            vec![
                ("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")),
                ("a.mtl", "newmtl x\nKd red green blue\n"),
            ],
            render("a.obj"),
            &["a.mtl:2", "Kd needs three numbers"],
        ),
        case(
            "MTL colour with one number (tobj 4 panics on it)",
            vec![("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")), ("a.mtl", "newmtl x\nKd 0.\n")],
            render("a.obj"),
            &["a.mtl:2", "Kd needs three numbers"],
        ),
        case(
            "MTL Ns that is not a number",
            vec![("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")), ("a.mtl", "newmtl x\nNs shiny\n")],
            render("a.obj"),
            &["a.mtl:2", "Ns needs one number"],
        ),
        case(
            "MTL that cannot be read (a folder)",
            vec![("a.obj", &format!("mtllib sub\n{TRI}f 1 2 3\n")), ("sub/x", "")],
            render("a.obj"),
            &["sub", "cannot read material library"],
        ),
        case(
            "missing texture",
            vec![
                ("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")),
                ("a.mtl", "newmtl x\nKd 1 1 1\nmap_Kd -bm 1 wood.png\n"),
            ],
            render("a.obj"),
            &["a.mtl:3", "map_Kd \"wood.png\"", "wood.png: cannot read"],
        ),
        case(
            "undecodable texture",
            vec![
                ("a.obj", &format!("mtllib a.mtl\n{TRI}usemtl x\nf 1 2 3\n")),
                ("a.mtl", "newmtl x\nKd 1 1 1\nmap_d mask.png\n"),
                ("mask.png", "\u{89}PNG, or so it says"),
            ],
            render("a.obj"),
            &["a.mtl:3", "map_d \"mask.png\"", "not a PNG or JPEG"],
        ),
        case("unknown scene extension", vec![("a.ply", "ply\n")], render("a.ply"), &["a.ply", "unknown scene type"]),
        // ---- TOML scene files ----
        toml_case("TOML syntax error", "[camera\nwidth = 4\n", &["s.toml:1:8"]),
        toml_case("unknown top-level key", &format!("colour = 1\n{mesh}"), &["s.toml:1:1", "unknown field `colour`"]),
        toml_case(
            "unknown camera key",
            &format!("[camera]\nfov = 40\nlens = 35\n{mesh}"),
            &["s.toml:3:1", "unknown field `lens`"],
        ),
        toml_case(
            "unknown mesh key",
            "[[mesh]]\nfile = \"m.obj\"\nscael = 2\n",
            &["s.toml:3:1", "unknown field `scael`"],
        ),
        toml_case("wrong type for spp", &format!("[render]\nspp = \"many\"\n{mesh}"), &["s.toml:2:7", "invalid type"]),
        toml_case("zero width", &format!("[camera]\nwidth = 0\n{mesh}"), &["s.toml:2:9", "resolution 0"]),
        toml_case("negative height", &format!("[camera]\nheight = -5\n{mesh}"), &["s.toml:2:10", "resolution -5"]),
        toml_case("absurd spp", &format!("[render]\nspp = 10000000000\n{mesh}"), &["s.toml:2:7", "spp 10000000000"]),
        toml_case("absurd bounces", &format!("[render]\nbounces = 5000\n{mesh}"), &["s.toml:2:11", "bounces 5000"]),
        toml_case("negative seed", &format!("[render]\nseed = -1\n{mesh}"), &["s.toml:2:8"]),
        toml_case(
            "non-positive time limit",
            &format!("[render]\ntime_limit = -1.0\n{mesh}"),
            &["s.toml:2:14", "time limit"],
        ),
        toml_case(
            "unknown sampler",
            &format!("[render]\nsampler = \"halton\"\n{mesh}"),
            &["s.toml:2:11", "halton", "sobol"],
        ),
        toml_case("NaN eye", &format!("[camera]\neye = [nan, 0, 0]\n{mesh}"), &["s.toml:2:7", "not finite"]),
        toml_case(
            "1e39 target",
            &format!("[camera]\ntarget = [0, 1e39, 0]\n{mesh}"),
            &["s.toml:2:10", "not finite or beyond"],
        ),
        toml_case("eye with two components", &format!("[camera]\neye = [1, 2]\n{mesh}"), &["s.toml:2:7"]),
        toml_case("field of view 200", &format!("[camera]\nfov = 200\n{mesh}"), &["s.toml:2:7", "field of view"]),
        toml_case(
            "eye equals target",
            &format!("[camera]\neye = [1, 1, 1]\ntarget = [1, 1, 1]\n{mesh}"),
            &["eye and target"],
        ),
        toml_case(
            "negative environment",
            &format!("environment = [-1, 0, 0]\n{mesh}"),
            &["s.toml:1:15", "non-negative"],
        ),
        toml_case("no meshes", "[camera]\nfov = 30\n", &["s.toml", "no [[mesh]]"]),
        toml_case("missing mesh file", "[[mesh]]\nfile = \"gone.obj\"\n", &["s.toml:2:8", "gone.obj", "cannot read"]),
        toml_case(
            "unknown whole-mesh material",
            "[[mesh]]\nfile = \"m.obj\"\nmaterial = \"gold\"\n",
            &["s.toml:3:12", "no material named \"gold\""],
        ),
        toml_case(
            "override of an MTL name the mesh lacks",
            "[materials.red]\nalbedo = [1, 0, 0]\n[[mesh]]\nfile = \"m.obj\"\nmaterials = { wall = \"red\" }\n",
            &["s.toml:5:22", "no MTL material named \"wall\""],
        ),
        toml_case(
            "rough plastic beyond α 1",
            &format!("[materials.paint]\ntype = \"plastic\"\nalpha = 1.5\n{mesh}"),
            &["s.toml:3:", "roughness alpha 1.5 must be within 0..=1"],
        ),
        toml_case(
            "roughplastic as a type",
            &format!("[materials.paint]\ntype = \"roughplastic\"\n{mesh}"),
            &["s.toml:2:", "use type = \"plastic\" with alpha"],
        ),
        toml_case(
            "unknown metal",
            &format!("[materials.m]\ntype = \"conductor\"\nmetal = \"Unobtainium\"\n{mesh}"),
            &["s.toml:", "unknown metal \"Unobtainium\"", "Au, Ag, Cu, Al, Cr"],
        ),
        toml_case(
            "conductor with an albedo",
            &format!("[materials.m]\ntype = \"conductor\"\nmetal = \"Au\"\nalbedo = [1, 1, 1]\n{mesh}"),
            &["s.toml:", "albedo does not apply to a conductor material", "metal, eta, k, alpha"],
        ),
        toml_case(
            "conductor without eta and k",
            &format!("[materials.m]\ntype = \"conductor\"\neta = [1, 1, 1]\n{mesh}"),
            &["s.toml:", "both eta and k"],
        ),
        toml_case(
            "conductor with a metal and eta",
            &format!("[materials.m]\ntype = \"conductor\"\nmetal = \"Cu\"\neta = [1, 1, 1]\nk = [1, 1, 1]\n{mesh}"),
            &["s.toml:", "either metal or eta and k"],
        ),
        toml_case(
            "roughness out of range",
            &format!("[materials.m]\ntype = \"conductor\"\nmetal = \"Al\"\nalpha = 1.5\n{mesh}"),
            &["s.toml:4:9", "alpha 1.5"],
        ),
        toml_case(
            "conductor keys on a diffuse material",
            &format!("[materials.m]\nalbedo = [0.5, 0.5, 0.5]\nk = [1, 1, 1]\n{mesh}"),
            &["s.toml:", "k does not apply to a diffuse material"],
        ),
        toml_case(
            "roughconductor as a type",
            &format!("[materials.m]\ntype = \"roughconductor\"\n{mesh}"),
            &["s.toml:2:8", "type = \"conductor\" with alpha"],
        ),
        toml_case(
            "rough dielectric as a type",
            &format!("[materials.g]\ntype = \"roughdielectric\"\n{mesh}"),
            &["s.toml:2:8", "type = \"dielectric\" with alpha"],
        ),
        toml_case(
            "index of refraction out of range",
            &format!("[materials.g]\ntype = \"dielectric\"\nior = 0\n{mesh}"),
            &["s.toml:3:7", "index of refraction 0"],
        ),
        toml_case(
            "ior on a conductor",
            &format!("[materials.g]\ntype = \"conductor\"\nmetal = \"Au\"\nior = 1.5\n{mesh}"),
            &["s.toml:", "ior does not apply to a conductor material"],
        ),
        toml_case(
            "metallic out of range",
            &format!("[materials.p]\ntype = \"principled\"\nmetallic = 2\n{mesh}"),
            &["s.toml:3:12", "2 must be within 0..=1"],
        ),
        toml_case(
            "alpha on a principled material",
            &format!("[materials.p]\ntype = \"principled\"\nalpha = 0.3\n{mesh}"),
            &["s.toml:", "alpha does not apply to a principled material", "roughness"],
        ),
        toml_case(
            "unknown material type",
            &format!("[materials.x]\ntype = \"velvet\"\n{mesh}"),
            &["s.toml:2:8", "unknown material type"],
        ),
        toml_case(
            "albedo above one",
            &format!("[materials.x]\nalbedo = [1.5, 0, 0]\n{mesh}"),
            &["s.toml:2:10", "albedo"],
        ),
        toml_case("zero scale", "[[mesh]]\nfile = \"m.obj\"\nscale = 0\n", &["s.toml:3:9", "non-zero"]),
        toml_case("scale of the wrong shape", "[[mesh]]\nfile = \"m.obj\"\nscale = [1, 2]\n", &["s.toml:3:9", "scale"]),
        toml_case(
            "transform overflowing f32",
            "[[mesh]]\nfile = \"m.obj\"\nscale = 5e17\ntranslate = [9e17, 0, 0]\n",
            &["s.toml:2:8", "placed vertex"],
        ),
        case("scene file that is not UTF-8", vec![("s.toml", "\u{0}")], render("s.toml"), &["s.toml"]),
        // ---- compiled scenes ----
        kdc_case("empty .kdc", Vec::new(), &["c.kdc", "truncated"]),
        kdc_case(
            "OBJ renamed .kdc",
            format!("{TRI}f 1 2 3\n").into_bytes(),
            &["c.kdc", "not a kdtrace compiled scene"],
        ),
        kdc_case("truncated .kdc", good[..good.len() - 100].to_vec(), &["c.kdc", "truncated"]),
        kdc_case(
            "corrupted .kdc",
            {
                let mut b = good.clone();
                let i = b.len() / 2;
                b[i] ^= 0x10;
                b
            },
            &["c.kdc", "checksum mismatch"],
        ),
        kdc_case(".kdc of another format version", crafted(&|p| p.version = 99), &["c.kdc", "format version 99"]),
        kdc_case(
            ".kdc with an absurd triangle count",
            crafted(&|p| p.header["counts"]["triangles"] = serde_json::json!(1u64 << 50)),
            &["c.kdc", "counts need"],
        ),
        kdc_case(
            ".kdc with a node child out of range",
            crafted(&|p| {
                let at = craft::section_offset(p, 4);
                craft::put_u32(p, at + 4, 12345 << 2)
            }),
            &["c.kdc", "k-d tree: node 0"],
        ),
        kdc_case(
            ".kdc with a material id out of range",
            crafted(&|p| {
                let at = craft::section_offset(p, 1);
                craft::put_u32(p, at, 1000)
            }),
            &["c.kdc", "material 1000 out of range"],
        ),
        // ---- command line ----
        case(
            "spp 0 on the command line",
            vec![],
            vec![
                "render".into(),
                repo("scenes/cornell-box.obj"),
                "--out".into(),
                "{dir}/x.png".into(),
                "--spp".into(),
                "0".into(),
            ],
            &["spp 0"],
        ),
        case(
            "adaptive threshold 0",
            vec![],
            [render_args(&repo("scenes/cornell-box.obj")), vec!["--adaptive".into(), "0".into()]].concat(),
            &["adaptive threshold 0"],
        ),
        case(
            "more pilot samples than spp",
            vec![],
            [
                render_args(&repo("scenes/cornell-box.obj")),
                vec!["--adaptive".into(), "0.05".into(), "--min-spp".into(), "8".into()],
            ]
            .concat(),
            &["min spp 8", "spp 1"],
        ),
        case(
            "unsupported output format",
            vec![],
            vec!["render".into(), repo("scenes/cornell-box.obj"), "--out".into(), "{dir}/x.bmp".into()],
            &["x.bmp"],
        ),
        case(
            "export of a .kdc",
            vec![("c.kdc", "")],
            vec!["export".into(), "{dir}/c.kdc".into(), "--out".into(), "{dir}/x.toml".into()],
            &["c.kdc", "cannot be exported"],
        ),
        case(
            "export to a non-TOML file",
            vec![],
            vec!["export".into(), repo("scenes/cornell-box.obj"), "--out".into(), "{dir}/x.json".into()],
            &["x.json", ".toml"],
        ),
        case(
            "compile to a non-.kdc file",
            vec![],
            vec!["compile".into(), repo("scenes/cornell-box.obj"), "--out".into(), "{dir}/x.bin".into()],
            &["x.bin", ".kdc"],
        ),
        // ---- outputs, checked before any work ----
        case(
            "--out and --variance name the same file",
            vec![],
            vec![
                "render".into(),
                repo("scenes/cornell-box.obj"),
                "--out".into(),
                "{dir}/x.exr".into(),
                "--variance".into(),
                "{dir}/./x.exr".into(),
            ],
            &["x.exr", "name the same file"],
        ),
        case(
            "an output folder that does not exist",
            vec![],
            vec!["render".into(), repo("scenes/cornell-box.obj"), "--out".into(), "{dir}/missing/x.png".into()],
            &["missing", "output folder"],
        ),
        case(
            "an output that is the input",
            vec![("m.toml", &format!("[[mesh]]\nfile = {:?}\n", repo("scenes/cornell-box.obj")))],
            vec!["export".into(), "{dir}/m.toml".into(), "--out".into(), "{dir}/m.toml".into()],
            &["m.toml", "also an input"],
        ),
        // ---- scenes with nothing to render, on every device and command ----
        case(
            "all triangles degenerate (CPU)",
            vec![("d.obj", DEGENERATE)],
            render("d.obj"),
            &["d.obj", "no renderable"],
        ),
        case(
            "all triangles degenerate (GPU)",
            vec![("d.obj", DEGENERATE)],
            [render("d.obj"), vec!["--device".into(), "gpu".into()]].concat(),
            &["d.obj", "no renderable"],
        ),
        case(
            "all triangles degenerate (tree)",
            vec![("d.obj", DEGENERATE)],
            vec!["tree".into(), "{dir}/d.obj".into()],
            &["d.obj", "no renderable"],
        ),
        case(
            "all triangles degenerate (compile)",
            vec![("d.obj", DEGENERATE)],
            vec!["compile".into(), "{dir}/d.obj".into(), "--out".into(), "{dir}/d.kdc".into()],
            &["d.obj", "no renderable"],
        ),
        // ---- strict values: fixed lengths, one albedo rule, tests that cannot be empty ----
        toml_case(
            "a camera eye of four numbers",
            "[camera]\neye = [0, 0, 1, 7]\n[[mesh]]\nfile = \"m.obj\"\n",
            &["s.toml:2:7", "exactly 3 numbers"],
        ),
        toml_case(
            "an environment of four numbers",
            "environment = [1, 1, 1, 1]\n[[mesh]]\nfile = \"m.obj\"\n",
            &["s.toml:1:15", "exactly 3 numbers"],
        ),
        toml_case(
            "an albedo of four numbers",
            "[materials.a]\nalbedo = [0.5, 0.5, 0.5, 0.5]\n[[mesh]]\nfile = \"m.obj\"\nmaterial = \"a\"\n",
            &["s.toml:2:10", "exactly 3 numbers"],
        ),
        case(
            "an MTL albedo above one",
            vec![("m.obj", &format!("mtllib m.mtl\n{TRI}usemtl a\nf 1 2 3\n")), ("m.mtl", "newmtl a\nKd 2 2 2\n")],
            render("m.obj"),
            &["m.mtl:2", "within 0..=1"],
        ),
        case(
            "an MTL colour of four numbers",
            vec![("m.obj", &format!("mtllib m.mtl\n{TRI}usemtl a\nf 1 2 3\n")), ("m.mtl", "newmtl a\nKe 1 1 1 1\n")],
            render("m.obj"),
            &["m.mtl:2", "three numbers, no more"],
        ),
        case(
            "a per-pixel test of one sample",
            vec![],
            vec![
                "compare".into(),
                repo("tests/data/cornell-box-mitsuba-32.exr"),
                repo("tests/data/cornell-box-mitsuba-32.exr"),
                "--variance".into(),
                repo("tests/data/cornell-box-mitsuba-32-stderr.exr"),
                "--spp".into(),
                "1".into(),
            ],
            &["--spp 1", "at least 2"],
        ),
        // ---- errors that name their line ----
        case(
            "a face corner that is not an index",
            vec![("a.obj", &format!("{TRI}f 1 2 3.0\n"))],
            render("a.obj"),
            &["a.obj:4", "3.0"],
        ),
        case(
            "a texture index that is not one",
            vec![("a.obj", &format!("{TRI}f 1/x 2 3\n"))],
            render("a.obj"),
            &["a.obj:4", "1/x"],
        ),
        case(
            "a vertex of five numbers",
            vec![("a.obj", "v 0 0 0 1 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")],
            render("a.obj"),
            &["a.obj:1", "not 5"],
        ),
        toml_case(
            "a camera whose eye is its target",
            "[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 1]\n[[mesh]]\nfile = \"m.obj\"\n",
            &["s.toml", "eye and target must differ"],
        ),
        // ---- scales beyond what renders correctly ----
        toml_case(
            "a scene scaled beyond the largest extent",
            "[[mesh]]\nfile = \"m.obj\"\nscale = 1e13\n",
            &["s.toml", "renders scenes up to"],
        ),
        toml_case(
            "a scene scaled below the smallest extent",
            "[[mesh]]\nfile = \"m.obj\"\nscale = 1e-12\n",
            &["s.toml", "of at least"],
        ),
        toml_case(
            "a camera beyond the largest extent",
            "[camera]\neye = [0, 0, 1e13]\n[[mesh]]\nfile = \"m.obj\"\n",
            &["s.toml", "camera", "5e12"],
        ),
        // glTF: t.gltf over b.bin (three vertices, then three u16 indices).
        case(
            "a glTF whose buffer file is missing",
            vec![("t.gltf", &gltf_tri("missing.bin", 3, 2, 4, ""))],
            render("t.gltf"),
            &["t.gltf", "buffer 0", "missing.bin"],
        ),
        gltf_case("a glTF accessor beyond its buffer view", gltf_tri("b.bin", 30, 2, 4, ""), &["t.gltf", "mesh 0", "accessor 0", "beyond"]),
        gltf_case("a glTF index beyond the vertices", gltf_tri("b.bin", 3, 7, 4, ""), &["t.gltf", "mesh 0", "index 7 out of range (3 vertices)"]),
        gltf_case("glTF points", gltf_tri("b.bin", 3, 2, 0, ""), &["t.gltf", "mesh 0", "Points", "not supported"]),
        gltf_case("glTF lines", gltf_tri("b.bin", 3, 2, 1, ""), &["t.gltf", "mesh 0", "Lines", "not supported"]),
        gltf_case(
            "a glTF requiring an extension kdtrace lacks",
            gltf_tri("b.bin", 3, 2, 4, r#""extensionsRequired": ["KHR_draco_mesh_compression"], "#),
            &["t.gltf", "requires", "KHR_draco_mesh_compression"],
        ),
        gltf_case(
            "a glTF naming an accessor it lacks",
            gltf_tri("b.bin", 3, 2, 4, "").replace("\"POSITION\": 0", "\"POSITION\": 9"),
            &["t.gltf", "invalid glTF", "POSITION"],
        ),
        gltf_case(
            "a glTF with broken base64",
            gltf_tri("data:application/octet-stream;base64,@@@", 3, 2, 4, ""),
            &["t.gltf", "buffer 0", "base64"],
        ),
        gltf_case("glTF that is not JSON", "{\"asset\": ".into(), &["t.gltf", "not glTF JSON"]),
        gltf_case(
            "a glTF clear coat above 1",
            gltf_tri("b.bin", 3, 2, 4, r#""materials": [{"extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 2}}}], "#)
                .replace("\"mode\": 4", "\"material\": 0, \"mode\": 4"),
            &["t.gltf", "material 0", "clearcoatFactor 2 is outside"],
        ),
        gltf_case(
            "a glTF clear coat roughness that is not a number",
            gltf_tri(
                "b.bin",
                3,
                2,
                4,
                r#""materials": [{"extensions": {"KHR_materials_clearcoat": {"clearcoatRoughnessFactor": "x"}}}], "#,
            )
            .replace("\"mode\": 4", "\"material\": 0, \"mode\": 4"),
            &["t.gltf", "material 0", "clearcoatRoughnessFactor is not a number"],
        ),
        case(
            "a truncated GLB",
            vec![("t.glb", "glTF\u{2}\0\0\0\u{ff}\0\0\0")],
            render("t.glb"),
            &["t.glb", "GLB"],
        ),
        case(
            "an orthographic glTF camera",
            vec![("t.gltf", &gltf_tri("b.bin", 3, 2, 4, "").replace("\"scenes\": [{\"nodes\": [0]}]", "\"scenes\": [{\"nodes\": [0, 1]}]").replace(
                "\"nodes\": [{\"mesh\": 0}]",
                "\"nodes\": [{\"mesh\": 0}, {\"camera\": 0}], \"cameras\": [{\"type\": \"orthographic\", \"orthographic\": {\"xmag\": 1, \"ymag\": 1, \"zfar\": 10, \"znear\": 0.1}}]",
            ))],
            [render("t.gltf"), vec!["--camera".into(), "0".into()]].concat(),
            &["t.gltf", "camera 0", "orthographic"],
        )
        .with_file("b.bin", gltf_bin(2)),
        {
            let mut c = gltf_case(
                "a scene file placing a broken glTF",
                gltf_tri("b.bin", 3, 9, 4, ""),
                &["s.toml", "t.gltf", "index 9 out of range"],
            );
            c.files.push(("s.toml", b"[[mesh]]\nfile = \"t.gltf\"\n".to_vec()));
            c.args = render("s.toml");
            c
        },
        case(
            "ray timing with no runs",
            vec![],
            vec!["rays".into(), repo("scenes/cornell-box.obj"), "--repeats".into(), "0".into()],
            &["--repeats"],
        ),
    ]
}

/// A glTF file of one triangle over the buffer `uri` (b.bin: three f32 vertices, then three u16
/// indices, the last `last_index`), its POSITION accessor of `count` elements, primitive `mode`,
/// `extra` JSON members first.
fn gltf_tri(uri: &str, count: u32, last_index: u16, mode: u32, extra: &str) -> String {
    format!(
        r#"{{{extra}"asset": {{"version": "2.0", "extras": {{"lastIndex": {last_index}, "x": 0}}}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
"meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "mode": {mode}}}]}}],
"buffers": [{{"uri": "{uri}", "byteLength": 42}}],
"bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}}],
"accessors": [{{"bufferView": 0, "componentType": 5126, "count": {count}, "type": "VEC3"}},
              {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}}]}}"#
    )
}

/// b.bin for `gltf_tri`, the last index `last`.
fn gltf_bin(last: u16) -> Vec<u8> {
    let mut b = Vec::new();
    for x in [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        b.extend(x.to_le_bytes());
    }
    for i in [0u16, 1, last] {
        b.extend(i.to_le_bytes());
    }
    b
}

impl Case {
    fn with_file(mut self, name: &'static str, bytes: Vec<u8>) -> Self {
        self.files.push((name, bytes));
        self
    }
}

fn gltf_case(name: &'static str, gltf: String, needles: &[&str]) -> Case {
    // The index the file's `last_index` names is written into b.bin (see `gltf_tri`).
    let last = gltf.split("\"lastIndex\": ").nth(1).and_then(|t| t.split(',').next()).and_then(|t| t.parse().ok());
    Case {
        name,
        files: vec![("t.gltf", gltf.into_bytes()), ("b.bin", gltf_bin(last.unwrap_or(2)))],
        args: render("t.gltf"),
        needles: needles.iter().map(|s| s.to_string()).collect(),
    }
}

/// Three triangles, each of zero area.
const DEGENERATE: &str = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 0 0\nf 1 2 3\nf 1 1 2\nf 4 1 1\n";

#[test]
fn every_broken_input_exits_2_naming_the_file_and_the_problem() {
    let cases = cases();
    assert!(cases.len() >= 30, "the table should hold at least 30 broken inputs, it has {}", cases.len());
    let root = std::env::temp_dir().join(format!("kdtrace-bad-{}", std::process::id()));
    let mut failures = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        let dir = root.join(format!("{i:02}"));
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in &c.files {
            let p = dir.join(name);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, bytes).unwrap();
        }
        let d = dir.to_string_lossy();
        let args: Vec<String> = c.args.iter().map(|a| a.replace("{dir}", &d)).collect();
        let o = Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        if o.status.code() != Some(2) || err.contains("panicked") {
            failures.push(format!("{i:02} {}: exit {:?}, stderr: {err}", c.name, o.status.code()));
            continue;
        }
        for needle in &c.needles {
            if !err.contains(needle.as_str()) {
                failures.push(format!("{i:02} {}: stderr lacks {needle:?}: {err}", c.name));
            }
        }
        if dir.join("never.png").exists() {
            failures.push(format!("{i:02} {}: a failed render wrote its output", c.name));
        }
    }
    assert!(failures.is_empty(), "{} of {} cases failed:\n{}", failures.len(), cases.len(), failures.join("\n"));
}
