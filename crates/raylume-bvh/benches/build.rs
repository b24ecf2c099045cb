//! Where the BVH build's time goes, stage by stage, on synthetic height-field grids of the
//! sizes in issue 19 (224², 707² and 1224² quads: 100,352, 999,698 and 2,996,352 triangles),
//! generated here, deterministically.
//!
//! First a table: for each grid and preset ([`BvhQuality::Fast`], [`BvhQuality::Quality`]),
//! the best of a few builds (`GpuBvh::build_profiled`) per stage: input checks and copies,
//! the coincident-box sort, spatial pre-splits, PLOC, reinsertion, leaf collapse, reinsertion
//! after the collapse, flattening to the GPU layout, the stats, then [`GpuBvh::validate`].
//! Then criterion groups over the smallest grid: the whole build per preset and `validate`.
//!
//! Run: `cargo bench -p raylume-bvh --bench build`. `RAYLUME_BENCH_QUICK=1`: the 100k and 1M
//! grids only, one build each past 100k, short criterion runs (about a minute on 2 cores).
//! `RAYLUME_BENCH_REPS=n`: builds per grid and preset in the table (best kept).
//! `RAYLUME_BENCH_GRIDS=707,1224`: the table over these grids (quads per side) only.

use std::time::{Duration, Instant};

use criterion::{Criterion, SamplingMode, Throughput};
use raylume_bvh::{BuildProfile, BvhLayout, BvhQuality, GpuBvh};
use raylume_scene::Triangle;

const QUALITIES: [BvhQuality; 3] = BvhQuality::ALL;

fn quick() -> bool {
    std::env::var("RAYLUME_BENCH_QUICK").is_ok_and(|v| v == "1")
}

/// Issue 19's height field of `n` x `n` quads (`raylume_scene::grid`).
fn grid(n: usize) -> Vec<Triangle> {
    raylume_scene::grid::height_field(n)
}

/// Per-stage minima over several profiles.
fn best(profiles: &[BuildProfile]) -> BuildProfile {
    let m = |f: fn(&BuildProfile) -> Duration| profiles.iter().map(f).min().unwrap();
    BuildProfile {
        prepare: m(|p| p.prepare),
        coincident_check: m(|p| p.coincident_check),
        pre_split: m(|p| p.pre_split),
        ploc: m(|p| p.ploc),
        depth_check: m(|p| p.depth_check),
        reinsertion: m(|p| p.reinsertion),
        collapse: m(|p| p.collapse),
        reinsertion_after_collapse: m(|p| p.reinsertion_after_collapse),
        flatten: m(|p| p.flatten),
        stats: m(|p| p.stats),
    }
}

fn ms(d: Duration) -> String {
    format!("{:.0}", d.as_secs_f64() * 1e3)
}

fn stage_table(sizes: &[usize]) {
    let reps_env = std::env::var("RAYLUME_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok());
    eprintln!(
        "| triangles | preset | layout | prepare | coincident | pre-split | PLOC | depth | reinsert | \
         collapse | reinsert 2 | flatten | stats | build total | validate | SAH | refs |"
    );
    eprintln!("| ---: | --- | --- |{}", " ---: |".repeat(14));
    for &n in sizes {
        let tris = grid(n);
        let reps = reps_env.unwrap_or(if quick() && n > 300 { 1 } else { 3 });
        for (q, layout) in QUALITIES
            .into_iter()
            .flat_map(|q| [(q, BvhLayout::Binary), (q, BvhLayout::Wide)])
        {
            let mut profiles = Vec::new();
            let mut totals = Vec::new();
            let mut validates = Vec::new();
            let mut last = None;
            for _ in 0..reps {
                let (bvh, p) = GpuBvh::build_profiled(&tris, &[], q, q.params(), layout).unwrap();
                let t = Instant::now();
                bvh.validate().unwrap();
                validates.push(t.elapsed());
                totals.push(bvh.stats.build_time);
                profiles.push(p);
                last = Some(bvh);
            }
            let (p, bvh) = (best(&profiles), last.unwrap());
            eprintln!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} | {} |",
                tris.len(),
                q.name(),
                layout.name(),
                ms(p.prepare),
                ms(p.coincident_check),
                ms(p.pre_split),
                ms(p.ploc),
                ms(p.depth_check),
                ms(p.reinsertion),
                ms(p.collapse),
                ms(p.reinsertion_after_collapse),
                ms(p.flatten),
                ms(p.stats),
                ms(*totals.iter().min().unwrap()),
                ms(*validates.iter().min().unwrap()),
                bvh.stats.sah_cost,
                bvh.stats.primitive_refs,
            );
        }
    }
    eprintln!(
        "(ms, best of the builds per stage; build total is the best whole build; the wide \
         layout has no collapse or second reinsertion, its flatten is obvhs' eight-wide \
         conversion)"
    );
}

fn main() {
    // RAYLUME_BENCH_GRIDS=707,1224: the table over these grids only (quads per side).
    let chosen: Option<Vec<usize>> = std::env::var("RAYLUME_BENCH_GRIDS")
        .ok()
        .map(|v| v.split(',').filter_map(|n| n.trim().parse().ok()).collect());
    let sizes: &[usize] = match &chosen {
        Some(v) => v,
        None if quick() => &[224, 707],
        None => &[224, 707, 1224],
    };
    stage_table(sizes);

    let mut c = Criterion::default().configure_from_args();
    if quick() {
        c = c
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(2));
    }
    let tris = grid(224);
    let mut group = c.benchmark_group("build/grid_100352");
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    group.throughput(Throughput::Elements(tris.len() as u64));
    for q in QUALITIES {
        group.bench_function(q.name(), |b| {
            b.iter(|| GpuBvh::build(&tris, &[], q).unwrap())
        });
        let bvh = GpuBvh::build(&tris, &[], q).unwrap();
        group.bench_function(format!("validate_{}", q.name()), |b| {
            b.iter(|| bvh.validate().unwrap())
        });
    }
    group.finish();
    c.final_summary();
}
