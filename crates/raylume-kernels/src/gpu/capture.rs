//! A test hook: copies of the wavefront's queue, keys and ray states just before one bounce
//! is traced, i.e. right after that bounce's rays were sorted (and permuted).

use raylume_gpu::{GpuContext, wgpu};

use super::{BatchPlan, GpuTracer};
use crate::KernelError;
use crate::gpu_types::RayState;

/// What bounce `depth` of the last batch of the last render was about to trace
/// ([`GpuTracer::capture_sort`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SortCapture {
    pub depth: u32,
    /// The plan of that batch.
    pub plan: BatchPlan,
    /// Live rays the bounce traces.
    pub count: u32,
    /// `rays[i]` for `i < count`: the index into `states` of the `i`-th ray the bounce reads.
    pub rays: Vec<u32>,
    /// `keys[i]`: the sort key of ray `rays[i]`, when the rays were sorted before this depth
    /// (otherwise whatever the key buffer held).
    pub keys: Vec<u32>,
    /// The state buffer the bounce reads (after `permute_rays`, the permuted one).
    pub states: Vec<RayState>,
    /// The box the keys quantise origins in (`SceneUniforms::scene_min`, `scene_extent`).
    pub scene_min: [f32; 3],
    pub scene_extent: [f32; 3],
}

pub(crate) struct CaptureBuffers {
    pub counts: wgpu::Buffer,
    pub keys: wgpu::Buffer,
    pub rays: wgpu::Buffer,
    pub states: wgpu::Buffer,
    pub capacity: u32,
}

pub(crate) struct Capture {
    pub depth: u32,
    pub buffers: Option<CaptureBuffers>,
    /// Set by the batch that copied: its plan and the key box.
    pub taken: Option<(BatchPlan, [f32; 3], [f32; 3])>,
}

impl CaptureBuffers {
    pub fn new(ctx: &GpuContext, capacity: u32) -> Result<Self, KernelError> {
        let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let n = u64::from(capacity);
        Ok(Self {
            counts: ctx.storage_buffer_zeroed("captured queue counts", 16, usage)?,
            keys: ctx.storage_buffer_zeroed("captured keys", n * 4, usage)?,
            rays: ctx.storage_buffer_zeroed("captured queue", n * 4, usage)?,
            states: ctx.storage_buffer_zeroed(
                "captured ray states",
                n * size_of::<RayState>() as u64,
                usage,
            )?,
            capacity,
        })
    }
}

impl GpuTracer<'_> {
    /// Test hook: from the next render on, copy what bounce `depth` reads (its queue, the key
    /// buffer and the ray states) just before it is traced, after any sort and permutation
    /// before it; [`GpuTracer::sort_capture`] reads the copy of the last wavefront batch.
    /// `None` turns it off. Costs a copy of the batch's ray states per batch.
    pub fn capture_sort(&mut self, depth: Option<u32>) {
        self.capture = depth.map(|depth| Capture {
            depth,
            buffers: None,
            taken: None,
        });
    }

    /// The copy [`GpuTracer::capture_sort`] asked for, if a wavefront batch reached that depth.
    pub fn sort_capture(&self) -> Result<Option<SortCapture>, KernelError> {
        let Some(c) = &self.capture else {
            return Ok(None);
        };
        let (Some(b), Some((plan, scene_min, scene_extent))) = (&c.buffers, c.taken) else {
            return Ok(None);
        };
        let counts: Vec<u32> = self.ctx.read_buffer(&b.counts, 4)?;
        let count = counts[(c.depth & 1) as usize].min(b.capacity);
        let n = count as usize;
        Ok(Some(SortCapture {
            depth: c.depth,
            plan,
            count,
            rays: self.ctx.read_buffer(&b.rays, n)?,
            keys: self.ctx.read_buffer(&b.keys, n)?,
            states: self.ctx.read_buffer(&b.states, b.capacity as usize)?,
            scene_min,
            scene_extent,
        }))
    }
}
