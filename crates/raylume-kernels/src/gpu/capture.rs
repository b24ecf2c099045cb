//! A test hook: copies of the wavefront's queue, keys and ray states just before one bounce
//! is traced, i.e. right after that bounce's rays were sorted (and permuted).

use raylume_gpu::{GpuContext, wgpu};

use super::batch::{BounceProbe, current_queue};
use super::clock::{Record, Stage};
use super::work::WorkBuffers;
use super::{BatchPlan, GpuTracer};
use crate::gpu_types::{RayState, SceneUniforms};
use crate::{KernelError, Schedule};

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

impl Capture {
    /// Before a render's batches: forget the last copy, and hold buffers for `capacity` rays
    /// when a batch may run the wavefront.
    pub fn prepare(
        &mut self,
        ctx: &GpuContext,
        capacity: u32,
        wavefront: bool,
    ) -> Result<(), KernelError> {
        self.taken = None;
        if wavefront && self.buffers.as_ref().is_none_or(|b| b.capacity != capacity) {
            self.buffers = None;
            self.buffers = Some(CaptureBuffers::new(ctx, capacity)?);
        }
        Ok(())
    }

    /// The probe a batch's recorder injects (when the buffers exist).
    pub fn probe(&self) -> Option<&dyn BounceProbe> {
        self.buffers.as_ref().map(|_| self as &dyn BounceProbe)
    }

    /// After a batch of `plan` with uniforms `u`: a wavefront batch that reached the depth
    /// copied it.
    pub fn batch_done(&mut self, plan: BatchPlan, u: &SceneUniforms, max_bounces: u32) {
        if plan.schedule == Schedule::Wavefront && self.depth <= max_bounces {
            self.taken = Some((plan, u.scene_min, u.scene_extent));
        }
    }
}

impl BounceProbe for Capture {
    /// At the captured depth: copies of the queue counts, the keys, the queue and the ray
    /// states the bounce reads (untimed).
    fn before_bounce<'r>(
        &'r self,
        depth: u32,
        w: &'r WorkBuffers,
        states: usize,
    ) -> Option<Stage<'r>> {
        let c = self.buffers.as_ref().filter(|_| depth == self.depth)?;
        let q = current_queue(depth);
        Some(Stage {
            label: "capture",
            depth: Some(depth),
            submit_after: false,
            record: Record::Untimed(Box::new(move |enc| {
                let size = |b: &wgpu::Buffer, d: &wgpu::Buffer| b.size().min(d.size());
                enc.copy_buffer_to_buffer(&w.queue_counts, 0, &c.counts, 0, 16);
                enc.copy_buffer_to_buffer(&w.ray_keys, 0, &c.keys, 0, size(&w.ray_keys, &c.keys));
                let rq = &w.ray_queues[q];
                enc.copy_buffer_to_buffer(rq, 0, &c.rays, 0, size(rq, &c.rays));
                let st = &w.ray_states[states];
                enc.copy_buffer_to_buffer(st, 0, &c.states, 0, size(st, &c.states));
            })),
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
        let count = counts[current_queue(c.depth)].min(b.capacity);
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
