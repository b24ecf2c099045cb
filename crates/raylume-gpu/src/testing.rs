//! What every GPU test calls first.

use std::sync::OnceLock;

use crate::{ContextOptions, GpuContext};

/// True when `RAYLUME_REQUIRE_GPU=1`: GPU tests must fail rather than skip (CI sets it).
pub fn gpu_required() -> bool {
    std::env::var("RAYLUME_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// A context shared by the tests of one test binary (lavapipe counts), or `None` after
/// printing a visible `SKIPPED` line. Panics instead when `RAYLUME_REQUIRE_GPU=1`.
pub fn context_or_skip(test: &str) -> Option<&'static GpuContext> {
    static CTX: OnceLock<Result<GpuContext, String>> = OnceLock::new();
    let ctx =
        CTX.get_or_init(|| GpuContext::new(&ContextOptions::default()).map_err(|e| e.to_string()));
    match ctx {
        Ok(c) => Some(c),
        Err(e) => {
            if gpu_required() {
                panic!("{test}: RAYLUME_REQUIRE_GPU=1 but no GPU context: {e}");
            }
            eprintln!(
                "SKIPPED {test}: no GPU adapter ({e}); set RAYLUME_REQUIRE_GPU=1 to fail instead"
            );
            None
        }
    }
}
