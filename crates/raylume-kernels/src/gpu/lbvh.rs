//! [`LbvhBuilder`]: the BVH built on the GPU, the paper's future work ("the BVH construction
//! takes a significant amount of time for the more complex scenes"): Karras' linear BVH
//! (`gpu/lbvh.wgsl` over raylume-bvh's [`LBVH_WGSL`](raylume_bvh::LBVH_WGSL)), the mirror of
//! [`raylume_bvh::lbvh::lbvh_binary`], node for node. The primitives' 63-bit Morton codes are
//! sorted by raylume-sort's radix sort (two stable 32-bit sorts: low words, then high), the
//! radix tree's inner nodes are found each by its own thread, and the boxes are filled in
//! by one refit pass per level (a node is finished at the pass after its last inner child,
//! so the pass that finishes the root is the tree's depth; a dispatch boundary orders each
//! pass's writes before the next one's reads, which atomics in one pass would not in WGSL).
//!
//! The tree is the [`BvhLayout::Binary`] layout with one primitive a leaf, in the radix
//! tree's order (inner node `i` at node `i`), over triangles only; its nodes and primitives
//! stay on the GPU for the tracer ([`ResidentBvh`], [`GpuScene::upload_resident`](super::GpuScene::upload_resident));
//! the CPU reads back the primitives' order only ([`ResidentBvh::read_back`] reads the rest).

use std::time::Instant;

use raylume_bvh::lbvh::{LBVH_AXIS_BITS, LbvhParams};
use raylume_bvh::{BvhNode, GpuBvh, MAX_STACK_DEPTH, Primitive};
use raylume_gpu::{GpuContext, wgpu};
use raylume_sort::{RadixSorter, SortLen, SortOptions};
use rayon::prelude::*;
use wgpu::util::DeviceExt;

use super::layout::{storage_entry, uniform_entry};
use crate::KernelError;

/// Threads per workgroup of the LBVH kernels.
pub const LBVH_WORKGROUP_SIZE: u32 = 256;

/// The kernels in the order a build runs them (the sorts between `lbvh_encode`,
/// `lbvh_high_keys` and `lbvh_gather`; `lbvh_refit` once per level).
const ENTRY_POINTS: [&str; 5] = [
    "lbvh_encode",
    "lbvh_high_keys",
    "lbvh_gather",
    "lbvh_inner",
    "lbvh_refit",
];

/// The builder's WGSL: the tree's types, the LBVH functions and `gpu/lbvh.wgsl`, with the
/// constants from Rust.
pub fn lbvh_source() -> String {
    let mut s = String::from("// raylume-kernels: the LBVH built on the GPU (gpu/lbvh.rs)\n");
    s += &format!("const LBVH_AXIS_BITS: u32 = {LBVH_AXIS_BITS}u;\n");
    s += &format!("const LBVH_WORKGROUP_SIZE: u32 = {LBVH_WORKGROUP_SIZE}u;\n");
    for part in [
        raylume_bvh::BVH_TYPES_WGSL,
        raylume_bvh::LBVH_WGSL,
        include_str!("lbvh.wgsl"),
    ] {
        s += "\n";
        s += part;
    }
    s
}

/// The base of a mapped range, shared by the tasks writing disjoint parts of it.
#[derive(Clone, Copy)]
struct SendPtr(std::ptr::NonNull<u8>);

// SAFETY: only used for writes to disjoint parts of one mapping, within its lifetime
// (`LbvhBuilder::build_triangles`).
unsafe impl Send for SendPtr {}
unsafe impl Sync for SendPtr {}

impl SendPtr {
    /// The address `offset` bytes in.
    fn at(self, offset: usize) -> *mut u8 {
        // SAFETY: callers stay within the mapping (see `build_triangles`).
        unsafe { self.0.as_ptr().add(offset) }
    }
}

/// The compiled LBVH kernels and a radix sorter, made once per context
/// ([`LbvhBuilder::build`] grows the sorter when a scene needs more).
pub struct LbvhBuilder {
    group_layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::ComputePipeline>,
    sorter: Option<RadixSorter>,
    seconds: f64,
}

impl std::fmt::Debug for LbvhBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LbvhBuilder")
            .field("sort_capacity", &self.sorter.as_ref().map(|s| s.max_len()))
            .finish()
    }
}

/// A BVH built on the GPU by [`LbvhBuilder::build`]: its nodes and leaf-order primitives
/// stay there (reading 3M triangles' nodes back and measuring them took longer than the
/// build); the CPU keeps the primitives' leaf order, which the scene's preparation needs
/// ([`GpuScene::upload_resident`](super::GpuScene::upload_resident)).
pub struct ResidentBvh {
    /// Leaf `k` holds scene triangle `order[k]`.
    order: Vec<u32>,
    /// `bvh_nodes` ([`BvhLayout::Binary`](raylume_bvh::BvhLayout::Binary), `COPY_SRC`).
    pub(crate) nodes: wgpu::Buffer,
    /// `bvh_primitives` (`COPY_SRC`).
    pub(crate) primitives: wgpu::Buffer,
    node_count: usize,
    max_depth: usize,
    gpu_seconds: f64,
    seconds: f64,
}

impl std::fmt::Debug for ResidentBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ResidentBvh")
            .field("node_count", &self.node_count)
            .field("max_depth", &self.max_depth)
            .field("gpu_seconds", &self.gpu_seconds)
            .finish()
    }
}

impl ResidentBvh {
    /// Inner nodes ([`BvhNode`]s): one fewer than the primitives (one for a single one).
    pub fn node_count(&self) -> usize {
        self.node_count
    }

    /// Nodes on the longest root-to-leaf path, the root counting 1.
    pub fn max_depth(&self) -> usize {
        self.max_depth
    }

    /// The leaves' order: leaf `k` (`bvh_primitives[k]`) is the scene's triangle `order[k]`.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Seconds from the build's call (the triangles' preparation and upload included) to the
    /// finished tree on the GPU, before the order's read-back.
    pub fn gpu_seconds(&self) -> f64 {
        self.gpu_seconds
    }

    /// Seconds [`LbvhBuilder::build`] took, the order's read-back and the leaf order on the
    /// CPU included.
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// The whole tree on the CPU: the nodes read back (for the CPU's traversal, checks, tests).
    pub fn read_back(&self, ctx: &GpuContext) -> Result<GpuBvh, KernelError> {
        let start = Instant::now();
        let mut bvh = GpuBvh {
            layout: raylume_bvh::BvhLayout::Binary,
            nodes: ctx.read_buffer::<BvhNode>(&self.nodes, self.node_count)?,
            wide_nodes: Vec::new(),
            primitives: ctx.read_buffer::<Primitive>(&self.primitives, self.order.len())?,
            triangle_count: self.order.len() as u32,
            sphere_count: 0,
            stats: Default::default(),
            cpu_arrays: Default::default(),
        };
        bvh.stats = raylume_bvh::BvhStats::of_lbvh(&bvh, self.max_depth, start);
        Ok(bvh)
    }
}

impl LbvhBuilder {
    /// Compiles the kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self, KernelError> {
        let start = Instant::now();
        let device = &ctx.device;
        let (group_layout, pipelines) = ctx.scoped("compiling the GPU BVH build", || {
            let mut entries: Vec<_> = (0..8).map(|b| storage_entry(b, b == 0)).collect();
            entries.push(uniform_entry(8, true));
            let group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("raylume lbvh"),
                entries: &entries,
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("raylume lbvh"),
                bind_group_layouts: &[Some(&group_layout)],
                immediate_size: 0,
            });
            let module = ctx.shader_module("raylume lbvh", &lbvh_source());
            let pipelines = ENTRY_POINTS
                .iter()
                .map(|entry| {
                    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(&pipeline_layout),
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        cache: None,
                    })
                })
                .collect();
            (group_layout, pipelines)
        })?;
        Ok(Self {
            group_layout,
            pipelines,
            sorter: None,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Seconds [`LbvhBuilder::new`] took (compiling).
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// Builds the tree over `source` (scene-order triangles: [`GpuBvh::lbvh_input`]) on the
    /// GPU. A tree deeper than [`MAX_STACK_DEPTH`] is [`raylume_bvh::BvhError::TooDeep`] (as
    /// [`KernelError::Bvh`]), for the caller to build on the CPU instead.
    pub fn build(
        &mut self,
        ctx: &GpuContext,
        source: &[Primitive],
    ) -> Result<ResidentBvh, KernelError> {
        let start = Instant::now();
        if let Some(p) = source
            .par_iter()
            .position_first(|p| !raylume_bvh::lbvh::lbvh_takes(p))
        {
            return Err(KernelError::InvalidScene(format!(
                "the GPU BVH build takes triangles only; primitive {p} is not one"
            )));
        }
        let params = LbvhParams::of_primitives(source);
        let buffer = ctx
            .storage_buffer("BVH build triangles", source, wgpu::BufferUsages::COPY_SRC)
            .map_err(KernelError::from_upload)?;
        self.build_over(ctx, buffer, params, start)
    }

    /// [`LbvhBuilder::build`] over a scene's `triangles` (checked as
    /// [`GpuBvh::lbvh_input`] checks them), written as [`Primitive`]s straight into the GPU's
    /// upload buffer on every core, their centres' bounds found in the same pass: no copy of
    /// them on the CPU (3M triangles are 144 MB of primitives).
    pub fn build_triangles(
        &mut self,
        ctx: &GpuContext,
        triangles: &[raylume_scene::Triangle],
    ) -> Result<ResidentBvh, KernelError> {
        let start = Instant::now();
        GpuBvh::check_triangles(triangles)?;
        let bytes = (triangles.len().max(1) * std::mem::size_of::<Primitive>()) as u64;
        ctx.check_fits("BVH build triangles", bytes)
            .map_err(KernelError::from_upload)?;
        let buffer = ctx.scoped("BVH build triangles", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("BVH build triangles"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: true,
            })
        })?;
        let bounds = {
            let mut view = buffer.slice(..).get_mapped_range_mut().map_err(|e| {
                raylume_gpu::GpuError::Map {
                    during: "writing the BVH build's triangles".into(),
                    detail: e.to_string(),
                }
            })?;
            // Each task writes its chunk's bytes once, from a copy made in the cache (mapped
            // memory may be write-combining: never read). wgpu's `WriteOnly` slices are not
            // `Send`, so the tasks share the range's base pointer.
            const CHUNK: usize = 1 << 14;
            let size = std::mem::size_of::<Primitive>();
            let mut range = view.slice(..triangles.len() * size);
            let base = SendPtr(range.as_raw_element_ptr());
            triangles
                .par_chunks(CHUNK)
                .enumerate()
                .map(|(c, tris)| {
                    let mut b = (glam::Vec3A::INFINITY, glam::Vec3A::NEG_INFINITY);
                    let prims: Vec<Primitive> = tris
                        .iter()
                        .enumerate()
                        .map(|(k, t)| {
                            let i = (c * CHUNK + k) as u32;
                            let p = Primitive::triangle(t.positions.map(|p| p.to_array()), i);
                            let centre = raylume_bvh::lbvh::primitive_centre(&p);
                            b = (b.0.min(centre), b.1.max(centre));
                            p
                        })
                        .collect();
                    let bytes: &[u8] = bytemuck::cast_slice(&prims);
                    // SAFETY: chunk `c` covers bytes `c * CHUNK * size ..` of the
                    // `triangles.len() * size` the range holds, disjoint from every other
                    // chunk's; the mapping outlives this parallel loop (`view` is dropped
                    // after it) and nothing else reads or writes it meanwhile.
                    unsafe {
                        std::ptr::copy_nonoverlapping(
                            bytes.as_ptr(),
                            base.at(c * CHUNK * size),
                            bytes.len(),
                        );
                    }
                    b
                })
                .reduce(
                    || (glam::Vec3A::INFINITY, glam::Vec3A::NEG_INFINITY),
                    |a, b| (a.0.min(b.0), a.1.max(b.1)),
                )
        };
        buffer.unmap();
        let params = LbvhParams::of_centre_bounds(bounds.0, bounds.1, triangles.len());
        self.build_over(ctx, buffer, params, start)
    }

    /// The build over `source_buffer` (the triangles as [`Primitive`]s, scene order) whose
    /// centres `params` grids.
    fn build_over(
        &mut self,
        ctx: &GpuContext,
        source_buffer: wgpu::Buffer,
        params: LbvhParams,
        start: Instant,
    ) -> Result<ResidentBvh, KernelError> {
        let n = params.count as usize;
        let count = params.count;
        let none = wgpu::BufferUsages::empty();
        let copy = wgpu::BufferUsages::COPY_SRC;
        if n < 2 {
            // No inner node to find: the reference's one-node tree; the source is the leaves.
            let mut root = BvhNode {
                left_index: raylume_bvh::INVALID_INDEX,
                right_index: raylume_bvh::INVALID_INDEX,
                ..Default::default()
            };
            if n == 1 {
                let p = ctx.read_buffer::<Primitive>(&source_buffer, 1)?;
                root = raylume_bvh::lbvh::lbvh_binary(&p).nodes[0];
            }
            let nodes = ctx
                .storage_buffer("BVH nodes", &[root], copy)
                .map_err(KernelError::from_upload)?;
            return Ok(ResidentBvh {
                order: (0..count).collect(),
                nodes,
                primitives: source_buffer,
                node_count: 1,
                max_depth: 1,
                gpu_seconds: start.elapsed().as_secs_f64(),
                seconds: start.elapsed().as_secs_f64(),
            });
        }
        if self.sorter.as_ref().is_none_or(|s| s.max_len() < count) {
            self.sorter = None;
            self.sorter = Some(RadixSorter::new(ctx, count, SortOptions::full_keys())?);
        }
        let sorter = self.sorter.as_ref().expect("made above");
        let words = |k: u64| k * n as u64 * 4;
        let zeroed = |label: &str, bytes: u64, usage| {
            ctx.storage_buffer_zeroed(label, bytes, usage)
                .map_err(KernelError::from_upload)
        };
        let unsorted = zeroed("BVH build codes", words(2), none)?;
        let keys = zeroed("BVH build sort keys", words(1), none)?;
        let values = zeroed("BVH build order", words(1), copy)?;
        let codes = zeroed("BVH build sorted codes", words(2), none)?;
        let primitives = zeroed("BVH primitives", words(12), copy)?;
        let nodes = zeroed("BVH nodes", (n as u64 - 1) * 64, copy)?;
        let state = zeroed("BVH build node heights", words(1), copy)?;

        // One parameter block per refit pass (pass 0: the other kernels), at dynamic offsets.
        let stride = u64::from(ctx.limits.min_uniform_buffer_offset_alignment).max(32);
        let passes = MAX_STACK_DEPTH as u32;
        let mut blocks = vec![0u8; (stride * u64::from(passes + 1)) as usize];
        for p in 0..=passes {
            let at = (u64::from(p) * stride) as usize;
            let block = LbvhParams {
                pass_index: p,
                ..params
            };
            blocks[at..at + 32].copy_from_slice(bytemuck::bytes_of(&block));
        }
        ctx.scoped(
            "building the BVH on the GPU",
            || -> Result<(), KernelError> {
                let uniforms = ctx
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("BVH build parameters"),
                        contents: &blocks,
                        usage: wgpu::BufferUsages::UNIFORM,
                    });
                let buffers = [
                    &source_buffer,
                    &unsorted,
                    &keys,
                    &values,
                    &codes,
                    &primitives,
                    &nodes,
                    &state,
                ];
                let mut entries: Vec<wgpu::BindGroupEntry> = buffers
                    .iter()
                    .enumerate()
                    .map(|(b, buffer)| wgpu::BindGroupEntry {
                        binding: b as u32,
                        resource: buffer.as_entire_binding(),
                    })
                    .collect();
                entries.push(wgpu::BindGroupEntry {
                    binding: 8,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &uniforms,
                        offset: 0,
                        size: wgpu::BufferSize::new(32),
                    }),
                });
                let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("raylume lbvh"),
                    layout: &self.group_layout,
                    entries: &entries,
                });
                let max_x = ctx.limits.max_compute_workgroups_per_dimension;
                let grid = |threads: u32| {
                    let groups = threads.div_ceil(LBVH_WORKGROUP_SIZE).max(1);
                    (groups.min(max_x), groups.div_ceil(max_x))
                };
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let run =
                    |enc: &mut wgpu::CommandEncoder, kernel: usize, pass: u32, threads: u32| {
                        let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some(ENTRY_POINTS[kernel]),
                            timestamp_writes: None,
                        });
                        cp.set_pipeline(&self.pipelines[kernel]);
                        cp.set_bind_group(0, &group, &[(u64::from(pass) * stride) as u32]);
                        let (x, y) = grid(threads);
                        cp.dispatch_workgroups(x, y, 1);
                    };
                run(&mut enc, 0, 0, count);
                sorter.encode(&mut enc, &keys, &values, SortLen::Fixed(count), None)?;
                run(&mut enc, 1, 0, count);
                sorter.encode(&mut enc, &keys, &values, SortLen::Fixed(count), None)?;
                run(&mut enc, 2, 0, count);
                run(&mut enc, 3, 0, count - 1);
                {
                    let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("lbvh_refit"),
                        timestamp_writes: None,
                    });
                    cp.set_pipeline(&self.pipelines[4]);
                    let (x, y) = grid(count - 1);
                    for p in 1..=passes {
                        cp.set_bind_group(0, &group, &[(u64::from(p) * stride) as u32]);
                        cp.dispatch_workgroups(x, y, 1);
                    }
                }
                ctx.queue.submit([enc.finish()]);
                Ok(())
            },
        )??;
        let depth = ctx.read_buffer::<u32>(&state, 1)?[0] as usize;
        let gpu_seconds = start.elapsed().as_secs_f64();
        if depth == 0 {
            return Err(KernelError::Bvh(raylume_bvh::BvhError::TooDeep {
                depth: MAX_STACK_DEPTH + 1,
                max: MAX_STACK_DEPTH,
            }));
        }
        let order = ctx.read_buffer::<u32>(&values, n)?;
        Ok(ResidentBvh {
            order,
            nodes,
            primitives,
            node_count: n - 1,
            max_depth: depth,
            gpu_seconds,
            seconds: start.elapsed().as_secs_f64(),
        })
    }
}
