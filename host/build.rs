//! Compiles `kernel/` to SPIR-V with rust-gpu; the module path reaches the host as `env!("kernel.spv")`.
use spirv_builder::SpirvBuilder;

fn main() {
    let manifest = std::path::PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let mut builder = SpirvBuilder::new(manifest.join("../kernel"), "spirv-unknown-vulkan1.2");
    // The shader is always optimised: an unoptimised module is ten times larger and naga rejects
    // its slice-holding structs.
    builder.release = true;
    builder.build_script.defaults = true;
    builder.build_script.env_shader_spv_path = Some(true);
    if let Err(e) = builder.build() {
        eprintln!("rust-gpu failed to compile kernel/: {e}");
        std::process::exit(1);
    }
}
