//! The `kdtrace` command line (`kdtrace::cli`).
use std::process::ExitCode;

/// The k-d build allocates event lists per node by the million; mimalloc serves that several
/// times faster than the system allocator.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    kdtrace::cli::run()
}
