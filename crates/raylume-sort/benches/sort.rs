//! Radix sort throughput: GPU sort of random 30-bit ray keys with index values, and the CPU
//! reference.
//!
//! GPU time comes from timestamps around the `sort_keys` pass when the adapter has them (else
//! wall-clock around submit + wait, which adds the submission latency). A table at the end gives
//! the median per size and variant, pairs/s and the effective bandwidth, counting 20 bytes per
//! pair per pass (upsweep reads the key; downsweep reads key + value and writes both).
//!
//! A plain binary: copy it from `target/release/deps/sort-*` and run `./sort-... --bench`.
//! Environment:
//! - `RAYLUME_SORT_BENCH_SIZES`: comma-separated pair counts (default `1048576,4194304,16777216`);
//! - `RAYLUME_SORT_BENCH_VARIANTS`: comma-separated variants `r{digit bits}` followed by any
//!   of `-wg{threads}`, `-i{keys per thread}` (else the defaults), `-shared` (no subgroups),
//!   `-indirect` (the length read from a GPU buffer, as the tracer does), `-sorted` (input
//!   already sorted), and `+stages` at the end (each kernel timed in its own pass; the table
//!   then lists the time per stage), e.g. `r8,r10,r8-shared,r8-wg128-i8,r8-indirect+stages`
//!   (default `r8,r10,r8-shared`);
//! - `RAYLUME_SORT_BENCH_CPU=0` skips the CPU reference.

use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput};
use raylume_gpu::{ContextOptions, GpuContext, Timestamps};
use raylume_sort::{RadixSorter, SortLen, SortOptions, sort_pairs_cpu};

fn sizes() -> Vec<u32> {
    std::env::var("RAYLUME_SORT_BENCH_SIZES")
        .unwrap_or_else(|_| "1048576,4194304,16777216".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect()
}

/// A variant: options, whether the length is indirect, whether the input is pre-sorted.
type Variant = (String, SortOptions, bool, bool);

fn variants() -> Vec<Variant> {
    std::env::var("RAYLUME_SORT_BENCH_VARIANTS")
        .unwrap_or_else(|_| "r8,r10,r8-shared".into())
        .split(',')
        .filter_map(|full| {
            let full = full.trim();
            let parsed = parse_variant(full);
            if parsed.is_none() {
                eprintln!("unknown variant {full:?}, skipped");
            }
            parsed
        })
        .collect()
}

/// `r{bits}` then any of `-wg{threads}`, `-i{keys per thread}`, `-shared`, `-indirect`,
/// `-sorted`, `+stages`.
fn parse_variant(full: &str) -> Option<Variant> {
    let (name, stages) = match full.strip_suffix("+stages") {
        Some(n) => (n, true),
        None => (full, false),
    };
    let mut parts = name.split('-');
    let bits: u32 = parts.next()?.strip_prefix('r')?.parse().ok()?;
    let mut opts = SortOptions::ray_keys()
        .with_radix_bits(bits)
        .with_stage_timestamps(stages);
    let (mut wg, mut items) = (None, None);
    let (mut indirect, mut sorted) = (false, false);
    for part in parts {
        match part {
            "shared" => opts = opts.with_subgroups(false),
            "indirect" => indirect = true,
            "sorted" => sorted = true,
            p if p.starts_with("wg") => wg = Some(p[2..].parse().ok()?),
            p if p.starts_with('i') => items = Some(p[1..].parse().ok()?),
            _ => return None,
        }
    }
    if let Some(i) = items {
        opts.items_per_thread = i;
    }
    if wg.is_some() {
        opts.workgroup_size = wg;
    }
    Some((full.to_string(), opts, indirect, sorted))
}

/// splitmix64 keys in the 30-bit range of ray keys.
fn random_keys(n: u32, seed: u64) -> Vec<u32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) as u32) & 0x3FFF_FFFF
        })
        .collect()
}

struct Row {
    variant: String,
    n: u32,
    passes: u32,
    times: Vec<f64>,
    clock: &'static str,
    /// Per stage label, the time of each run (stage timestamps only).
    stages: Vec<(&'static str, Vec<f64>)>,
}

/// One sort of `n` pairs, restored from pristine copies first; returns the sort's GPU time.
struct GpuCase<'a> {
    ctx: &'a GpuContext,
    sorter: RadixSorter,
    n: u32,
    src_keys: wgpu::Buffer,
    src_values: wgpu::Buffer,
    keys: wgpu::Buffer,
    values: wgpu::Buffer,
    /// Holds `n` when the length is read on the GPU.
    count: Option<wgpu::Buffer>,
    timestamps: Option<Timestamps>,
    stages: Vec<(&'static str, Vec<f64>)>,
}

impl GpuCase<'_> {
    fn run_once(&mut self) -> f64 {
        let bytes = u64::from(self.n) * 4;
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.src_keys, 0, &self.keys, 0, bytes);
        encoder.copy_buffer_to_buffer(&self.src_values, 0, &self.values, 0, bytes);
        if self.timestamps.is_none() {
            self.ctx.queue.submit([encoder.finish()]);
            self.ctx.wait("bench restore").expect("restore");
            encoder = self.ctx.device.create_command_encoder(&Default::default());
        }
        self.sorter
            .encode(
                &mut encoder,
                &self.keys,
                &self.values,
                match &self.count {
                    Some(count_buffer) => SortLen::Indirect {
                        count_buffer,
                        offset: 0,
                    },
                    None => SortLen::Fixed(self.n),
                },
                self.timestamps.as_mut(),
            )
            .expect("encode");
        if let Some(ts) = &self.timestamps {
            ts.resolve(&mut encoder);
        }
        let start = Instant::now();
        self.ctx.queue.submit([encoder.finish()]);
        match &mut self.timestamps {
            Some(ts) => {
                let times = ts.read(self.ctx).expect("timestamps");
                // Sum per label over the passes of this run.
                let mut per_label: Vec<(&'static str, f64)> = Vec::new();
                for &(label, t) in &times {
                    match per_label.iter_mut().find(|(l, _)| *l == label) {
                        Some(e) => e.1 += t,
                        None => per_label.push((label, t)),
                    }
                }
                if times.len() > 1 {
                    for (label, t) in per_label {
                        match self.stages.iter_mut().find(|(l, _)| *l == label) {
                            Some(e) => e.1.push(t),
                            None => self.stages.push((label, vec![t])),
                        }
                    }
                }
                times.iter().map(|(_, t)| t).sum()
            }
            None => {
                self.ctx.wait("bench sort").expect("sort");
                start.elapsed().as_secs_f64()
            }
        }
    }
}

fn bench_gpu(c: &mut Criterion, ctx: &GpuContext, rows: &mut Vec<Row>) {
    let max = (ctx.max_binding_bytes() / 4) as u32;
    for (name, opts, indirect, presorted) in variants() {
        let mut group = c.benchmark_group(format!("gpu_sort/{name}"));
        group.sample_size(10);
        for n in sizes() {
            if n == 0 || n > max {
                eprintln!("{name}: {n} pairs skipped (adapter allows up to {max})");
                continue;
            }
            let sorter = match RadixSorter::new(ctx, n, opts) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("{name}: {e}");
                    continue;
                }
            };
            eprintln!("{name}, {n} pairs: {:?}", sorter.plan());
            let passes = sorter.plan().passes;
            let mut keys = random_keys(n, u64::from(n));
            if presorted {
                keys.sort_unstable();
            }
            let values: Vec<u32> = (0..n).collect();
            let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
            let mut case = GpuCase {
                ctx,
                n,
                src_keys: ctx.storage_buffer("bench src keys", &keys, copy).unwrap(),
                src_values: ctx
                    .storage_buffer("bench src values", &values, copy)
                    .unwrap(),
                keys: ctx.storage_buffer("bench keys", &keys, copy).unwrap(),
                values: ctx.storage_buffer("bench values", &values, copy).unwrap(),
                count: indirect.then(|| ctx.storage_buffer("bench count", &[n], copy).unwrap()),
                timestamps: Timestamps::new(ctx, 3 + 3 * passes),
                stages: Vec::new(),
                sorter,
            };
            // Once, checked, so that a broken sort is never timed.
            case.run_once();
            let sorted: Vec<u32> = ctx.read_buffer(&case.keys, n as usize).unwrap();
            assert!(
                sorted.windows(2).all(|w| w[0] <= w[1]),
                "{name}: not sorted"
            );
            let clock = if case.timestamps.is_some() {
                "gpu timestamps"
            } else {
                "wall clock"
            };
            let mut times = Vec::new();
            group.throughput(Throughput::Elements(u64::from(n)));
            group.bench_function(BenchmarkId::from_parameter(n), |b| {
                b.iter_custom(|iters| {
                    let mut total = 0.0;
                    for _ in 0..iters {
                        let t = case.run_once();
                        times.push(t);
                        total += t;
                    }
                    Duration::from_secs_f64(total)
                })
            });
            rows.push(Row {
                variant: name.clone(),
                n,
                passes,
                times,
                clock,
                stages: std::mem::take(&mut case.stages),
            });
        }
        group.finish();
    }
}

fn bench_cpu(c: &mut Criterion) {
    let mut group = c.benchmark_group("cpu_sort_pairs");
    group.sample_size(10);
    for n in sizes() {
        let keys = random_keys(n, u64::from(n));
        let values: Vec<u32> = (0..n).collect();
        group.throughput(Throughput::Elements(u64::from(n)));
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter(|| sort_pairs_cpu(&keys, &values, 30))
        });
    }
    group.finish();
}

fn main() {
    let mut c = Criterion::default()
        .configure_from_args()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    let mut rows = Vec::new();
    match GpuContext::new(&ContextOptions::default()) {
        Ok(ctx) => {
            eprintln!("adapter: {}", ctx.describe());
            bench_gpu(&mut c, &ctx, &mut rows);
        }
        Err(e) => eprintln!("no GPU, GPU benches skipped: {e}"),
    }
    if std::env::var("RAYLUME_SORT_BENCH_CPU").as_deref() != Ok("0") {
        bench_cpu(&mut c);
    }
    c.final_summary();

    if !rows.is_empty() {
        println!("\nvariant     pairs       passes  median ms   min ms    Mpairs/s  GB/s   clock");
        for r in &mut rows {
            if r.times.is_empty() {
                continue;
            }
            r.times.sort_by(f64::total_cmp);
            let median = r.times[r.times.len() / 2];
            let min = r.times[0];
            let bytes = f64::from(r.n) * 20.0 * f64::from(r.passes);
            println!(
                "{:<11} {:<11} {:<7} {:<11.3} {:<9.3} {:<9.1} {:<6.1} {}",
                r.variant,
                r.n,
                r.passes,
                median * 1e3,
                min * 1e3,
                f64::from(r.n) / median * 1e-6,
                bytes / median * 1e-9,
                r.clock
            );
            for (label, times) in &mut r.stages {
                times.sort_by(f64::total_cmp);
                println!(
                    "    {label:<16} median {:.3} ms (all passes)",
                    times[times.len() / 2] * 1e3
                );
            }
        }
    }
}
