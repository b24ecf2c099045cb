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
    let Some(mut ts) = raylume_gpu::Timestamps::new(ctx, 1) else {
        eprintln!(
            "adapter {} has no timestamps; nothing to check",
            ctx.describe()
        );
        return;
    };
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
