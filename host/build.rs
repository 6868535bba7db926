//! Compiles `kernel/` to SPIR-V with rust-gpu; the module path reaches the host as `env!("kernel.spv")`.
use spirv_builder::SpirvBuilder;
use std::path::PathBuf;

/// The rust-gpu backend's dylib, named by the same path whichever cargo command runs this script.
///
/// spirv-builder otherwise takes the first copy on the library path: cargo's build and test put
/// the copy uplifted to `target/release` first, its check and clippy only the one in the
/// backend's own build folder. The two paths (hard links to one file) give the kernel's build two
/// different flags, so after `cargo clippy` the next build compiled the whole kernel again.
fn codegen_backend() -> Option<PathBuf> {
    let name = format!("{}rustc_codegen_spirv{}", std::env::consts::DLL_PREFIX, std::env::consts::DLL_SUFFIX);
    let paths = std::env::var_os("LD_LIBRARY_PATH")?;
    std::env::split_paths(&paths)
        .map(|dir| dir.join(&name))
        .find(|path| path.is_file() && path.components().any(|c| c.as_os_str() == "rustc_codegen_spirv"))
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let mut builder = SpirvBuilder::new(manifest.join("../kernel"), "spirv-unknown-vulkan1.2");
    // The shader is always optimised: an unoptimised module is ten times larger and naga rejects
    // its slice-holding structs.
    builder.release = true;
    builder.build_script.defaults = true;
    builder.build_script.env_shader_spv_path = Some(true);
    builder.rustc_codegen_spirv_location = codegen_backend();
    if let Err(e) = builder.build() {
        eprintln!("rust-gpu failed to compile kernel/: {e}");
        std::process::exit(1);
    }
}
