use crate::{GpuContext, GpuError};

/// Named GPU timestamps written at the start and end of compute passes.
///
/// `new` returns `None` when the adapter has no `TIMESTAMP_QUERY`; callers then fall back to
/// wall-clock time around a `wait`. Usage per submission: `writes("propagate")` for each pass,
/// `resolve(&mut encoder)` before `finish`, then after submitting, `read(ctx)` gives
/// `(label, seconds)` per pass and makes room for the next submission.
pub struct Timestamps {
    query_set: wgpu::QuerySet,
    resolve_buf: wgpu::Buffer,
    capacity: u32,
    labels: Vec<&'static str>,
    period_ns: f64,
}

impl Timestamps {
    /// Room for `passes` passes per submission.
    pub fn new(ctx: &GpuContext, passes: u32) -> Option<Self> {
        if !ctx.has_timestamps() || passes == 0 {
            return None;
        }
        let capacity = passes * 2;
        let query_set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("raylume timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: capacity,
        });
        let resolve_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("raylume timestamps resolve"),
            size: u64::from(capacity) * 8,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(Self {
            query_set,
            resolve_buf,
            capacity,
            labels: Vec::new(),
            period_ns: f64::from(ctx.queue.get_timestamp_period()),
        })
    }

    /// Timestamp writes for the next pass, or `None` when this submission's room is used up.
    pub fn writes(&mut self, label: &'static str) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let i = self.labels.len() as u32 * 2;
        if i + 2 > self.capacity {
            return None;
        }
        self.labels.push(label);
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.query_set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        })
    }

    /// Records the resolve of this submission's queries; call once before `encoder.finish()`.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let n = self.labels.len() as u32 * 2;
        if n > 0 {
            encoder.resolve_query_set(&self.query_set, 0..n, &self.resolve_buf, 0);
        }
    }

    /// Reads this submission's pass durations (in seconds) and clears the labels.
    pub fn read(&mut self, ctx: &GpuContext) -> Result<Vec<(&'static str, f64)>, GpuError> {
        let n = self.labels.len() * 2;
        if n == 0 {
            return Ok(Vec::new());
        }
        let ticks: Vec<u64> = ctx.read_buffer(&self.resolve_buf, n)?;
        let out = self
            .labels
            .iter()
            .enumerate()
            .map(|(k, l)| {
                let dt = ticks[2 * k + 1].saturating_sub(ticks[2 * k]);
                (*l, dt as f64 * self.period_ns * 1e-9)
            })
            .collect();
        self.labels.clear();
        Ok(out)
    }
}
