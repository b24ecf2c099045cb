//! The GPU tracer: the scene uploaded once into storage buffers, pipelines specialised on the
//! scene's features, and the two schedules (megakernel, wavefront) run batch by batch.

mod clock;
mod layout;
mod shader;
mod work;

pub use shader::{pipeline_constants, tracer_source};

use std::collections::HashMap;
use std::time::Instant;

use raylume_bvh::{BvhNode, GpuBvh, Primitive};
use raylume_gpu::{GpuContext, wgpu};
use raylume_scene::{Feature, Features, Scene};

use crate::batches::{Batch, dispatch_size, plan_batches};
use crate::gpu_types::{GpuMaterial, RayState, SceneUniforms, TextureHeader, TriangleShading};
use crate::scene_data::SceneData;
use crate::{KernelError, Schedule, TraceOutput, TraceSettings, WORKGROUP_SIZE};
use clock::StageClock;
use layout::{bind_group_layouts, upload};
use work::WorkBuffers;

/// Statistics of a render whose image stays on the GPU ([`GpuTracer::render_to_buffer`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TraceStats {
    pub rays_traced: u64,
    pub dropped_samples: u64,
    /// As [`TraceOutput::timings`].
    pub timings: Vec<(&'static str, f64)>,
}

/// The wavefront's queue buffers, for the reordering pass the facade inserts between
/// `propagate` launches (raylume-sort) and for tests.
///
/// After `propagate` at bounce `d` (queue parity `q = d & 1`): `queue_counts` holds `u32`
/// lengths, `[q]` the rays it advanced (`n`), `[1 - q]` those still alive; `ray_keys[t]` for
/// `t < n` is the sort key of the ray `ray_queues[q][t]` (raylume-sort's
/// `DEAD_RAY_KEY` if it ended); `ray_queues[1 - q][..live]` holds the live rays, compacted,
/// which bounce `d + 1` reads. Sorting the pairs `(ray_keys, ray_queues[q])` over `n` and
/// copying `ray_queues[q]` onto `ray_queues[1 - q]` gives bounce `d + 1` the live rays in key
/// order. All four buffers allow `COPY_SRC` and `COPY_DST`.
pub struct WavefrontBuffers<'b> {
    pub ray_keys: &'b wgpu::Buffer,
    pub ray_queues: [&'b wgpu::Buffer; 2],
    pub queue_counts: &'b wgpu::Buffer,
}

/// A batch and its per-sample radiance in slot order ([`GpuTracer::last_batch_samples`]).
pub type BatchSamples = (Batch, Vec<[f32; 3]>);

/// The scene's storage buffers and their bind group (group 0).
struct SceneBuffers {
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// Renders a scene on the GPU. Holds the uploaded scene, the compiled pipelines and the
/// work buffers of the last render size; `render` may be called many times.
pub struct GpuTracer<'a> {
    ctx: &'a GpuContext,
    data: SceneData,
    features: Features,
    scene: SceneBuffers,
    work_layout: wgpu::BindGroupLayout,
    args_layout: wgpu::BindGroupLayout,
    /// Groups 0 and 1: every entry point but `prepare_propagate`.
    pipeline_layout: wgpu::PipelineLayout,
    /// Groups 0, 1 and 2: `prepare_propagate`.
    prepare_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    pipelines: HashMap<&'static str, wgpu::ComputePipeline>,
    work: Option<WorkBuffers>,
    /// The last batch rendered (its samples stay in the sample-radiance buffer).
    last_batch: Option<Batch>,
    /// A cap on rays per batch below the adapter's own ([`GpuTracer::set_batch_ray_limit`]).
    batch_ray_limit: Option<u64>,
    upload_seconds: f64,
}

impl<'a> GpuTracer<'a> {
    /// Uploads `scene` (with its BVH `bvh`) and builds pipelines specialised on
    /// `scene.features()`.
    pub fn new(ctx: &'a GpuContext, scene: &Scene, bvh: &GpuBvh) -> Result<Self, KernelError> {
        Self::with_features(ctx, scene, bvh, scene.features())
    }

    /// As [`GpuTracer::new`], with pipelines specialised on `features` instead (which must
    /// include the scene's own; [`Features::all`] gives the unspecialised reference).
    pub fn with_features(
        ctx: &'a GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        features: Features,
    ) -> Result<Self, KernelError> {
        // Bloom is a post pass, not tracer code.
        let needed = scene.features().bits() & !(Feature::Bloom as u32);
        let missing = Features::from_bits(needed & !features.bits());
        if missing != Features::NONE {
            return Err(KernelError::InvalidScene(format!(
                "pipelines specialised without features the scene uses: {missing}"
            )));
        }
        let start = Instant::now();
        let mut data = SceneData::new(scene, bvh)?;
        let device = &ctx.device;

        let uniforms = ctx.scoped("creating the scene uniform buffer", || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raylume scene uniforms"),
                size: size_of::<SceneUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        let nodes = upload::<BvhNode>(ctx, "BVH nodes", &bvh.nodes)?;
        let primitives = upload::<Primitive>(ctx, "BVH primitives", &bvh.primitives)?;
        let materials = upload::<GpuMaterial>(ctx, "materials", &data.materials)?;
        let prim_materials =
            upload::<u32>(ctx, "primitive material indices", &data.prim_materials)?;
        // A pipeline that may read shading data gets a full-length array even when no triangle
        // has any, so that its reads stay in bounds.
        let needs_shading =
            features.contains(Feature::ShadingNormals) || features.contains(Feature::Textures);
        let zero_shading;
        let shading: &[TriangleShading] = if data.triangle_shading.is_empty() && needs_shading {
            zero_shading = vec![TriangleShading::default(); data.prim_materials.len()];
            &zero_shading
        } else {
            &data.triangle_shading
        };
        let shading = upload::<TriangleShading>(ctx, "triangle shading data", shading)?;
        let headers = upload::<TextureHeader>(ctx, "texture headers", &data.texture_headers)?;
        let texels = upload::<f32>(ctx, "texture and environment-map data", &data.texels)?;

        let [scene_layout, work_layout, args_layout] = bind_group_layouts(device);
        let (bind_group, pipeline_layout, prepare_layout, module) =
            ctx.scoped("building the tracer's shader and layouts", || {
                let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("raylume scene"),
                    layout: &scene_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: uniforms.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: nodes.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: primitives.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: materials.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: prim_materials.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: shading.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 6,
                            resource: headers.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 7,
                            resource: texels.as_entire_binding(),
                        },
                    ],
                });
                let pipeline_layout =
                    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("raylume tracer"),
                        bind_group_layouts: &[Some(&scene_layout), Some(&work_layout)],
                        immediate_size: 0,
                    });
                let prepare_layout =
                    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("raylume prepare_propagate"),
                        bind_group_layouts: &[
                            Some(&scene_layout),
                            Some(&work_layout),
                            Some(&args_layout),
                        ],
                        immediate_size: 0,
                    });
                let module = ctx.shader_module(
                    "raylume tracer",
                    &tracer_source(ctx.limits.max_compute_workgroups_per_dimension),
                );
                (bind_group, pipeline_layout, prepare_layout, module)
            })?;
        ctx.wait("uploading the scene")?;
        // Only what the uniforms need stays on the CPU.
        data.texels = Vec::new();
        data.triangle_shading = Vec::new();
        Ok(Self {
            ctx,
            data,
            features,
            scene: SceneBuffers {
                uniforms,
                bind_group,
            },
            work_layout,
            args_layout,
            pipeline_layout,
            prepare_layout,
            module,
            pipelines: HashMap::new(),
            work: None,
            last_batch: None,
            batch_ray_limit: None,
            upload_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Caps the rays (pixel samples) of one batch below what the adapter's binding size
    /// allows, e.g. to bound memory; `None` restores the adapter's limit. Batches then hold
    /// fewer samples per pixel, or a range of the pixels when even one sample of every pixel
    /// exceeds the cap. The image does not depend on it.
    pub fn set_batch_ray_limit(&mut self, limit: Option<u64>) {
        self.batch_ray_limit = limit;
    }

    /// The features the pipelines are specialised on.
    pub fn features(&self) -> Features {
        self.features
    }

    /// The compute pipeline of entry point `entry`, compiled on first use.
    fn pipeline(&mut self, entry: &'static str) -> Result<wgpu::ComputePipeline, KernelError> {
        if let Some(p) = self.pipelines.get(entry) {
            return Ok(p.clone());
        }
        let constants = pipeline_constants(self.features);
        let p = self
            .ctx
            .scoped(&format!("compiling the `{entry}` pipeline"), || {
                self.ctx
                    .device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(if entry == "prepare_propagate" {
                            &self.prepare_layout
                        } else {
                            &self.pipeline_layout
                        }),
                        module: &self.module,
                        entry_point: Some(entry),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants: &constants,
                            zero_initialize_workgroup_memory: true,
                        },
                        cache: None,
                    })
            })?;
        self.pipelines.insert(entry, p.clone());
        Ok(p)
    }

    /// The image of the last render: mean linear radiance, packed RGB `f32` triples
    /// (12 bytes per pixel, row-major, top row first; the buffer may be padded at the end),
    /// usable as a storage buffer or copy source (e.g. by a bloom pass before read-back).
    pub fn image_buffer(&self) -> Option<&wgpu::Buffer> {
        self.work.as_ref().map(|w| &w.accumulation)
    }

    /// The wavefront's queues, keys and counts, once a wavefront render has allocated them.
    pub fn wavefront_buffers(&self) -> Option<WavefrontBuffers<'_>> {
        let w = self.work.as_ref()?;
        (w.key.schedule == Schedule::Wavefront).then_some(WavefrontBuffers {
            ray_keys: &w.ray_keys,
            ray_queues: [&w.ray_queues[0], &w.ray_queues[1]],
            queue_counts: &w.queue_counts,
        })
    }

    /// The per-sample radiance of the last batch of the last render, in slot order (slot
    /// `s * pixel_count + p` holds sample `sample_begin + s` of pixel `pixel_begin + p`), and
    /// that batch: for tests and debugging (compare with [`crate::CpuTracer::sample_radiance`]).
    pub fn last_batch_samples(&self) -> Result<Option<BatchSamples>, KernelError> {
        let (Some(b), Some(w)) = (self.last_batch, self.work.as_ref()) else {
            return Ok(None);
        };
        let samples = self
            .ctx
            .read_buffer(&w.sample_radiance, b.rays() as usize)?;
        Ok(Some((b, samples)))
    }

    /// Renders and reads the image back.
    pub fn render(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<TraceOutput, KernelError> {
        let stats = self.render_to_buffer(settings, progress)?;
        let pixels = (settings.width * settings.height) as usize;
        let buffer = &self
            .work
            .as_ref()
            .expect("render_to_buffer allocates work")
            .accumulation;
        let radiance = self.ctx.read_buffer::<[f32; 3]>(buffer, pixels)?;
        Ok(TraceOutput {
            radiance,
            rays_traced: stats.rays_traced,
            dropped_samples: stats.dropped_samples,
            timings: stats.timings,
        })
    }

    /// Renders, leaving the image on the GPU in [`GpuTracer::image_buffer`]. Calls
    /// `progress(spp_done, spp_total)` after each batch.
    pub fn render_to_buffer(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<TraceStats, KernelError> {
        settings.validate()?;
        let ctx = self.ctx;
        let pixels = settings.width * settings.height;
        let per_ray = match settings.schedule {
            Schedule::Wavefront => size_of::<RayState>() as u64,
            Schedule::Megakernel => 12,
        };
        let max_rays =
            (ctx.max_binding_bytes() / per_ray).min(self.batch_ray_limit.unwrap_or(u64::MAX));
        let batches = plan_batches(pixels, settings.spp, settings.batch_spp, max_rays);
        let capacity = batches.iter().map(|b| b.rays()).max().unwrap_or(1);
        let key = work::WorkKey {
            schedule: settings.schedule,
            capacity,
            pixels,
            batches: batches.len() as u32,
            bounces: settings.max_bounces + 1,
        };
        if self.work.as_ref().is_none_or(|w| w.key != key) {
            self.work = None; // free the old buffers first
            self.work = Some(WorkBuffers::new(
                ctx,
                &self.work_layout,
                &self.args_layout,
                key,
            )?);
        }
        let stages: &[&'static str] = match settings.schedule {
            Schedule::Megakernel => &["trace_paths", "resolve"],
            Schedule::Wavefront => &["raygen", "prepare_propagate", "propagate", "resolve"],
        };
        let mut pipes = HashMap::new();
        for s in stages {
            pipes.insert(*s, self.pipeline(s)?);
        }
        let work = self.work.as_ref().expect("allocated above");
        work.reset(ctx, settings.max_bounces)?;

        let base = self.data.uniforms(settings);
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension;
        let mut clock = StageClock::new(ctx);
        let mut samples_done = 0u64;
        let start = Instant::now();
        for (bi, b) in batches.iter().enumerate() {
            let u = SceneUniforms {
                sample_begin: b.sample_begin,
                sample_count: b.sample_count,
                pixel_begin: b.pixel_begin,
                pixel_count: b.pixel_count,
                batch_index: bi as u32,
                resolve_scale: if b.last_for_pixels {
                    1.0 / settings.spp as f32
                } else {
                    1.0
                },
                rays_in_batch: b.rays(),
                queue_capacity: capacity,
                ..base
            };
            ctx.queue
                .write_buffer(&self.scene.uniforms, 0, bytemuck::bytes_of(&u));
            let ray_groups = dispatch_size(b.rays(), WORKGROUP_SIZE, max_dim);
            let pixel_groups = dispatch_size(b.pixel_count, WORKGROUP_SIZE, max_dim);
            let scene_bg = &self.scene.bind_group;
            // Group 1 of bounce `depth` (0 for every other stage): its parity's queues and its
            // bounce uniforms.
            let bind = |pass: &mut wgpu::ComputePass<'_>,
                        pipe: &wgpu::ComputePipeline,
                        depth: u32| {
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, scene_bg, &[]);
                let parity = (depth & 1) as usize;
                pass.set_bind_group(1, &work.bind_groups[parity], &[depth * work.bounce_stride]);
            };
            let resolve = |pass: &mut wgpu::ComputePass<'_>| {
                bind(pass, &pipes["resolve"], 0);
                pass.dispatch_workgroups(pixel_groups.0, pixel_groups.1, 1);
            };
            let during = format!("rendering batch {} of {}", bi + 1, batches.len());
            match settings.schedule {
                Schedule::Megakernel => {
                    let trace_paths = |pass: &mut wgpu::ComputePass<'_>| {
                        bind(pass, &pipes["trace_paths"], 0);
                        pass.dispatch_workgroups(ray_groups.0, ray_groups.1, 1);
                    };
                    clock.run(
                        &during,
                        &[("trace_paths", &trace_paths), ("resolve", &resolve)],
                    )?;
                }
                Schedule::Wavefront => {
                    let raygen = |pass: &mut wgpu::ComputePass<'_>| {
                        bind(pass, &pipes["raygen"], 0);
                        pass.dispatch_workgroups(ray_groups.0, ray_groups.1, 1);
                    };
                    let propagate = |pass: &mut wgpu::ComputePass<'_>| {
                        for depth in 0..=settings.max_bounces {
                            bind(pass, &pipes["prepare_propagate"], depth);
                            pass.set_bind_group(2, &work.args_bind_group, &[]);
                            pass.dispatch_workgroups(1, 1, 1);
                            bind(pass, &pipes["propagate"], depth);
                            pass.dispatch_workgroups_indirect(&work.dispatch_args, 0);
                        }
                    };
                    clock.run(
                        &during,
                        &[
                            ("raygen", &raygen),
                            ("propagate", &propagate),
                            ("resolve", &resolve),
                        ],
                    )?;
                }
            }
            samples_done += u64::from(b.rays());
            progress((samples_done / u64::from(pixels)) as u32, settings.spp);
        }
        let trace = start.elapsed().as_secs_f64();
        self.last_batch = batches.last().copied();
        let stats: Vec<u32> = ctx.read_buffer(&work.batch_stats, 4 * batches.len())?;
        let (mut rays_traced, mut dropped_samples) = (0u64, 0u64);
        for s in stats.chunks_exact(4) {
            rays_traced += u64::from(s[0]) | (u64::from(s[1]) << 32);
            dropped_samples += u64::from(s[2]);
        }
        let mut timings = vec![("upload", self.upload_seconds)];
        for (label, _) in [
            ("raygen", ()),
            ("propagate", ()),
            ("trace_paths", ()),
            ("resolve", ()),
        ] {
            if let Some(t) = clock.total(label) {
                timings.push((label, t));
            }
        }
        timings.push(("trace", trace));
        Ok(TraceStats {
            rays_traced,
            dropped_samples,
            timings,
        })
    }
}
