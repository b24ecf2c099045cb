//! What every GPU test calls first.
//!
//! A test without an adapter cannot check anything, and Rust's test harness has no way for a
//! test to mark itself ignored at run time: it passes. So that such a pass is not mistaken for
//! a check, [`context_or_skip`] (and [`report_skip`] for any other skip) writes a line
//!
//! ```text
//! SKIPPED (no GPU adapter): storage_round_trip
//! ```
//!
//! straight to the process's standard error, which the harness does not capture (it captures
//! only `print!`/`eprint!`), so the line shows in the ordinary `cargo test` output beside the
//! test's `ok`. With `RAYLUME_REQUIRE_GPU=1` (CI) the test fails instead.
//!
//! Also [`check_wgsl_struct`], the layout check of WGSL structs shared with Rust.

use std::collections::HashSet;
use std::io::Write;
use std::sync::{Mutex, OnceLock};

use crate::{ContextOptions, GpuContext};

/// True when `RAYLUME_REQUIRE_GPU=1`: GPU tests must fail rather than skip (CI sets it).
pub fn gpu_required() -> bool {
    std::env::var("RAYLUME_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// The running test's name: the harness names each test's thread after it (with
/// `--test-threads=1` too); `fallback` where that is not so.
pub fn current_test(fallback: &str) -> String {
    match std::thread::current().name() {
        Some(name) if name != "main" => name.to_string(),
        _ => fallback.to_string(),
    }
}

/// Writes `SKIPPED (reason): test` to standard error past the harness's capture, so that it
/// shows in `cargo test`'s output although the test passes; once per test and reason (a test
/// that asks for the GPU once per case gets one line). `test` names the test when the thread
/// does not (see [`current_test`]). What is skipped is the test's GPU part: some tests run
/// checks on the CPU before or besides it.
pub fn report_skip(test: &str, reason: &str) {
    static SEEN: Mutex<Option<HashSet<String>>> = Mutex::new(None);
    let line = format!("SKIPPED ({reason}): {}\n", current_test(test));
    let mut seen = SEEN.lock().unwrap_or_else(|p| p.into_inner());
    if !seen.get_or_insert_with(HashSet::new).insert(line.clone()) {
        return;
    }
    // Not `eprintln!`: the harness captures that and shows it only for failing tests.
    let mut err = std::io::stderr().lock();
    let _ = err.write_all(line.as_bytes());
    let _ = err.flush();
}

/// A context shared by the tests of one test binary (lavapipe counts), or `None` after
/// reporting the skip with [`report_skip`]. Panics instead when `RAYLUME_REQUIRE_GPU=1`.
pub fn context_or_skip(test: &str) -> Option<&'static GpuContext> {
    static CTX: OnceLock<Result<GpuContext, String>> = OnceLock::new();
    let ctx =
        CTX.get_or_init(|| GpuContext::new(&ContextOptions::default()).map_err(|e| e.to_string()));
    match ctx {
        Ok(c) => Some(c),
        Err(e) => {
            if gpu_required() {
                panic!(
                    "{}: RAYLUME_REQUIRE_GPU=1 but no GPU context: {e}",
                    current_test(test)
                );
            }
            // Why, once per test binary; then one short line per skipped test.
            static WHY: std::sync::Once = std::sync::Once::new();
            WHY.call_once(|| {
                let mut err = std::io::stderr().lock();
                let _ = writeln!(
                    err,
                    "GPU tests of this binary are skipped: {e}; set RAYLUME_REQUIRE_GPU=1 to \
                     fail instead"
                );
            });
            report_skip(test, "no GPU adapter");
            None
        }
    }
}

/// [`context_or_skip`]'s context when its adapter has subgroups (the wavefront's walk and
/// shadow stages need them), else `None` after reporting the skip (a GPU without subgroups
/// is not an error, even with `RAYLUME_REQUIRE_GPU=1`: those stages are then not built).
pub fn subgroup_context_or_skip(test: &str) -> Option<&'static GpuContext> {
    let ctx = context_or_skip(test)?;
    if ctx.has_subgroups() {
        Some(ctx)
    } else {
        report_skip(test, "the adapter has no subgroups");
        None
    }
}

/// A context of its own on the same adapter as [`context_or_skip`]'s, whose storage-binding
/// limit is lowered to `max_binding_bytes` ([`GpuContext::new_with_binding_limit`]): what the
/// tests of the "too large for a binding" paths use, so that they run on every adapter, an
/// H200's 2 GiB binding included. `None` (reported) without an adapter; panics when
/// `RAYLUME_REQUIRE_GPU=1` or when the limited device cannot be created.
pub fn context_with_binding_limit_or_skip(
    test: &str,
    max_binding_bytes: u64,
) -> Option<GpuContext> {
    context_or_skip(test)?;
    let ctx =
        GpuContext::new_with_binding_limit(&ContextOptions::default(), Some(max_binding_bytes))
            .unwrap_or_else(|e| {
                panic!(
                    "{}: a device with a {max_binding_bytes}-byte binding limit: {e}",
                    current_test(test)
                )
            });
    assert!(
        ctx.max_binding_bytes() <= max_binding_bytes
            && ctx.limits.max_storage_buffer_binding_size <= max_binding_bytes,
        "the lowered limit is in force"
    );
    Some(ctx)
}

/// Asserts that the WGSL struct `name` in `module` has Rust's `size` and `(member, offset)`
/// list (naga's layouter computes the WGSL side; the caller gives Rust's, from `size_of!` and
/// `offset_of!`): the check every crate with WGSL structs shared with Rust runs in its tests.
pub fn check_wgsl_struct(
    module: &crate::wgpu::naga::Module,
    layouter: &crate::wgpu::naga::proc::Layouter,
    name: &str,
    size: usize,
    fields: &[(&str, usize)],
) {
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("WGSL has no struct {name}"));
    let crate::wgpu::naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{name} is not a struct in WGSL");
    };
    assert_eq!(*span as usize, size, "size of {name}");
    assert_eq!(
        layouter[handle].size as usize, size,
        "layout size of {name}"
    );
    let wgsl: Vec<(&str, usize)> = members
        .iter()
        .map(|m| (m.name.as_deref().unwrap_or("?"), m.offset as usize))
        .collect();
    assert_eq!(wgsl, fields, "members and offsets of {name}");
}
