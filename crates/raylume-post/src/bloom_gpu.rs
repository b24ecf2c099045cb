//! Bloom on the GPU: the four kernels of `bloom.wgsl`, recorded into the caller's encoder.

use std::num::NonZeroU64;
use std::sync::Mutex;

use raylume_gpu::{GpuContext, GpuError, Timestamps};
use wgpu::util::DeviceExt;

use crate::PostError;
use crate::bloom::BloomParams;
use crate::error::check_image;
use crate::gpu_types::{BloomUniforms, WORKGROUP_SIZE};

/// The WGSL source of the bloom kernels.
pub const BLOOM_WGSL: &str = include_str!("bloom.wgsl");

/// The stages in the order they run: WGSL entry point, Rust mirror, wgpu label and timestamp
/// label are all this name.
pub const BLOOM_STAGES: [&str; 4] = ["bloom_threshold", "bloom_h", "bloom_v", "bloom_add"];

/// Bytes per pixel of the image format: packed RGB f32 triples.
pub const PIXEL_BYTES: u64 = 12;

fn bind(buffer: &wgpu::Buffer, size: Option<NonZeroU64>) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: 0,
        size,
    })
}

/// Scratch images reused between calls while they are large enough.
struct Scratch {
    bright: wgpu::Buffer,
    tmp: wgpu::Buffer,
    bytes: u64,
}

/// The bloom pipelines, created once per device, and cached scratch buffers.
///
/// The image is a storage buffer of `width * height` packed RGB f32 triples (`array<f32>` in
/// WGSL, 12 bytes per pixel, row-major, pixel `(x, y)` at floats `3 * (y * width + x) + 0..3`),
/// which is what the tracer's `resolve` writes. It may be larger than that; only the first
/// `width * height * 12` bytes are bound.
pub struct GpuBloom {
    layout: wgpu::BindGroupLayout,
    /// One per stage, in [`BLOOM_STAGES`] order.
    pipelines: [wgpu::ComputePipeline; 4],
    scratch: Mutex<Option<Scratch>>,
    /// Workgroups per dispatch dimension before the dispatch folds into 2D: the device limit,
    /// lowered by tests to exercise the fold.
    max_groups_per_dim: u32,
}

impl std::fmt::Debug for GpuBloom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuBloom").finish_non_exhaustive()
    }
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl GpuBloom {
    /// Compiles `bloom.wgsl` and creates one pipeline per stage.
    pub fn new(ctx: &GpuContext) -> Result<Self, PostError> {
        let dev = &ctx.device;
        let (layout, pipelines) = ctx.scoped("creating the bloom pipelines", || {
            let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("bloom.wgsl"),
                source: wgpu::ShaderSource::Wgsl(BLOOM_WGSL.into()),
            });
            let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("bloom"),
                entries: &[
                    wgpu::BindGroupLayoutEntry {
                        binding: 0,
                        visibility: wgpu::ShaderStages::COMPUTE,
                        ty: wgpu::BindingType::Buffer {
                            ty: wgpu::BufferBindingType::Uniform,
                            has_dynamic_offset: false,
                            min_binding_size: NonZeroU64::new(size_of::<BloomUniforms>() as u64),
                        },
                        count: None,
                    },
                    storage_entry(1, true),
                    storage_entry(2, false),
                ],
            });
            let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("bloom"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipelines = BLOOM_STAGES.map(|stage| {
                dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(stage),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(stage),
                    compilation_options: Default::default(),
                    cache: None,
                })
            });
            (layout, pipelines)
        })?;
        Ok(Self {
            layout,
            pipelines,
            scratch: Mutex::new(None),
            max_groups_per_dim: ctx.limits.max_compute_workgroups_per_dimension,
        })
    }

    /// Lowers the number of workgroups per dispatch dimension (at least 1), so that tests can
    /// exercise the 2D fold that images of over 16.7M pixels need.
    #[doc(hidden)]
    pub fn with_max_groups_per_dim(mut self, n: u32) -> Self {
        self.max_groups_per_dim = n.clamp(1, self.max_groups_per_dim);
        self
    }

    /// Records bloom over `image` into `encoder`: four compute passes named after
    /// [`BLOOM_STAGES`], each with a timestamp pair when `timestamps` has room. Nothing is
    /// recorded when `params.strength == 0`. The image stays on the GPU; the caller submits.
    ///
    /// `image` needs `STORAGE` usage and at least `width * height * 12` bytes (see
    /// [`GpuBloom`] for the layout). Two scratch images of the same size are allocated on
    /// first use and kept for later calls.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        image: &wgpu::Buffer,
        width: u32,
        height: u32,
        params: BloomParams,
        mut timestamps: Option<&mut Timestamps>,
    ) -> Result<(), PostError> {
        params.validate()?;
        if width == 0 || height == 0 {
            return Err(PostError::ZeroSize {
                what: "bloom image",
                width,
                height,
            });
        }
        let pixels = u64::from(width) * u64::from(height);
        let bytes = pixels * PIXEL_BYTES;
        if pixels * 3 > u64::from(u32::MAX) {
            return Err(GpuError::TooLarge {
                what: "bloom image (32-bit float indices)".into(),
                bytes,
                limit: u64::from(u32::MAX) / 3 * PIXEL_BYTES,
                adapter: ctx.info.name.clone(),
            }
            .into());
        }
        ctx.check_fits("bloom image", bytes)?;
        if image.size() < bytes {
            return Err(PostError::BadBuffer {
                what: "bloom image buffer",
                detail: format!(
                    "holds {} bytes but a {width}x{height} image of RGB f32 triples needs {bytes}",
                    image.size()
                ),
            });
        }
        if !image.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(PostError::BadBuffer {
                what: "bloom image buffer",
                detail: format!("needs STORAGE usage, has {:?}", image.usage()),
            });
        }
        if params.is_identity() {
            return Ok(());
        }
        let groups = pixels.div_ceil(u64::from(WORKGROUP_SIZE));
        let max_dim = u64::from(self.max_groups_per_dim);
        let gx = groups.min(max_dim);
        let gy = groups.div_ceil(gx);
        if gy > max_dim {
            return Err(GpuError::TooLarge {
                what: "bloom dispatch".into(),
                bytes,
                limit: max_dim * max_dim * u64::from(WORKGROUP_SIZE) * PIXEL_BYTES,
                adapter: ctx.info.name.clone(),
            }
            .into());
        }

        let mut scratch = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let s: &Scratch = match &mut *scratch {
            Some(s) if s.bytes >= bytes => s,
            slot => slot.insert(Scratch {
                bright: ctx.storage_buffer_zeroed(
                    "bloom bright",
                    bytes,
                    wgpu::BufferUsages::empty(),
                )?,
                tmp: ctx.storage_buffer_zeroed("bloom tmp", bytes, wgpu::BufferUsages::empty())?,
                bytes,
            }),
        };

        let uniforms = BloomUniforms {
            width,
            height,
            radius: params.radius,
            threshold: params.threshold,
            strength: params.strength,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        };
        let size = NonZeroU64::new(bytes);
        let bind_groups = ctx.scoped("encoding bloom", || {
            let ubuf = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("bloom uniforms"),
                    contents: bytemuck::bytes_of(&uniforms),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            // (src, dst) per stage, as the table at the top of bloom.wgsl says.
            let pairs = [
                (image, &s.bright),
                (&s.bright, &s.tmp),
                (&s.tmp, &s.bright),
                (&s.bright, image),
            ];
            pairs.map(|(src, dst)| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("bloom"),
                    layout: &self.layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: ubuf.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: bind(src, size),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: bind(dst, size),
                        },
                    ],
                })
            })
        })?;
        for ((stage, pipeline), group) in BLOOM_STAGES.iter().zip(&self.pipelines).zip(&bind_groups)
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(stage),
                timestamp_writes: timestamps.as_deref_mut().and_then(|t| t.writes(stage)),
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(gx as u32, gy as u32, 1);
        }
        Ok(())
    }

    /// Uploads `pixels`, applies bloom on the GPU, and reads the result back. For tests and
    /// one-off use; a renderer calls [`GpuBloom::encode`] on the buffer it already has.
    pub fn run(
        &self,
        ctx: &GpuContext,
        pixels: &[[f32; 3]],
        width: u32,
        height: u32,
        params: BloomParams,
    ) -> Result<Vec<[f32; 3]>, PostError> {
        params.validate()?;
        check_image("bloom image", pixels.len(), width, height)?;
        let image = ctx.storage_buffer("bloom image", pixels, wgpu::BufferUsages::COPY_SRC)?;
        let mut encoder = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bloom"),
            });
        self.encode(ctx, &mut encoder, &image, width, height, params, None)?;
        ctx.scoped("running bloom", || ctx.queue.submit([encoder.finish()]))?;
        Ok(ctx.read_buffer(&image, pixels.len())?)
    }
}

/// Applies bloom to `pixels` on the GPU and returns the result: compiles the pipelines, uploads,
/// runs and reads back. Convenient for tests; keep a [`GpuBloom`] to run it more than once.
pub fn bloom_gpu(
    ctx: &GpuContext,
    pixels: &[[f32; 3]],
    width: u32,
    height: u32,
    params: BloomParams,
) -> Result<Vec<[f32; 3]>, PostError> {
    GpuBloom::new(ctx)?.run(ctx, pixels, width, height, params)
}
