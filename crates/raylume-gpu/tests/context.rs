//! The context's contract on whatever adapter this machine has (lavapipe in CI).

use raylume_gpu::{GpuError, testing::context_or_skip, wgpu};

#[test]
fn storage_round_trip() {
    let Some(ctx) = context_or_skip("storage_round_trip") else {
        return;
    };
    let data: Vec<u32> = (0..1000).map(|i| i * 7 + 3).collect();
    let buf = ctx
        .storage_buffer("round trip", &data, wgpu::BufferUsages::COPY_SRC)
        .unwrap();
    let back: Vec<u32> = ctx.read_buffer(&buf, data.len()).unwrap();
    assert_eq!(back, data);
}

#[test]
fn oversized_buffer_is_a_typed_error() {
    let Some(ctx) = context_or_skip("oversized_buffer_is_a_typed_error") else {
        return;
    };
    let too_big = ctx.max_binding_bytes() + 16;
    let err = ctx
        .storage_buffer_zeroed("a huge ray buffer", too_big, wgpu::BufferUsages::empty())
        .unwrap_err();
    match &err {
        GpuError::TooLarge {
            what, bytes, limit, ..
        } => {
            assert_eq!(what, "a huge ray buffer");
            assert_eq!(*bytes, too_big);
            assert_eq!(*limit, ctx.max_binding_bytes());
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
    assert!(err.to_string().contains("CPU backend"), "{err}");
}

#[test]
fn shader_errors_come_back_as_validation_errors() {
    let Some(ctx) = context_or_skip("shader_errors_come_back_as_validation_errors") else {
        return;
    };
    let err = ctx
        .scoped("compiling a broken shader", || {
            ctx.device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("broken"),
                    source: wgpu::ShaderSource::Wgsl("fn main( { }".into()),
                })
        })
        .unwrap_err();
    match err {
        GpuError::Validation { during, .. } => assert_eq!(during, "compiling a broken shader"),
        other => panic!("expected Validation, got {other:?}"),
    }
    // The context stays usable after a caught error.
    ctx.check_health("after").unwrap();
}

#[test]
fn timestamps_time_a_pass() {
    let Some(ctx) = context_or_skip("timestamps_time_a_pass") else {
        return;
    };
    // No room asked for: no timestamps, on any adapter.
    assert!(raylume_gpu::Timestamps::new(ctx, 0).is_none());
    let Some(mut ts) = raylume_gpu::Timestamps::new(ctx, 1) else {
        // Only an adapter without the feature may refuse (lavapipe and the H100/H200 have it).
        assert!(
            !ctx.has_timestamps(),
            "{} has TIMESTAMP_QUERY but Timestamps::new refused",
            ctx.describe()
        );
        assert!(raylume_gpu::Timestamps::new(ctx, 8).is_none());
        if raylume_gpu::testing::gpu_required() {
            panic!(
                "RAYLUME_REQUIRE_GPU=1 but {} has no timestamps: nothing timed",
                ctx.describe()
            );
        }
        raylume_gpu::testing::report_skip(
            "timestamps_time_a_pass",
            &format!("{} has no timestamp queries", ctx.describe()),
        );
        return;
    };
    assert!(ctx.has_timestamps());
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    {
        let _pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("empty"),
            timestamp_writes: ts.writes("empty"),
        });
    }
    assert!(ts.writes("no room").is_none(), "capacity is one pass");
    ts.resolve(&mut enc);
    ctx.queue.submit([enc.finish()]);
    let t = ts.read(ctx).unwrap();
    assert_eq!(t.len(), 1);
    assert_eq!(t[0].0, "empty");
    assert!(t[0].1 >= 0.0 && t[0].1 < 1.0, "{t:?}");
}

/// Regression test: after `Device::destroy` (what a driver reset looks like to wgpu), creating
/// a buffer panicked inside wgpu (`create_buffer_init` could not map it), because wgpu reports
/// the loss only from a poll. Every `scoped` call now polls and checks first.
#[test]
fn a_destroyed_device_is_device_lost_not_a_panic() {
    if context_or_skip("a_destroyed_device_is_device_lost_not_a_panic").is_none() {
        return;
    }
    // Its own context: the shared one must survive.
    let ctx = raylume_gpu::GpuContext::new(&raylume_gpu::ContextOptions::default()).unwrap();
    ctx.device.destroy();
    let err = ctx
        .storage_buffer("scene data", &[1u32, 2, 3], wgpu::BufferUsages::empty())
        .unwrap_err();
    match &err {
        GpuError::DeviceLost { during, .. } => assert_eq!(during, "scene data"),
        other => panic!("expected DeviceLost, got {other:?}"),
    }
    assert!(err.to_string().contains("use the CPU backend"), "{err}");
    assert!(matches!(
        ctx.read_buffer::<u32>(
            &ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size: 16,
                usage: wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            4
        ),
        Err(GpuError::DeviceLost { .. })
    ));
}
