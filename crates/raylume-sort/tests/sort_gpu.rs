//! The GPU radix sort against the CPU reference (`sort_pairs_cpu`), on lavapipe or any adapter.
//! Values are the original indices, so comparing with a stable CPU sort checks the permutation,
//! the order and the stability at once; `assert_sorted_stably` checks the last two directly too.

use raylume_gpu::{GpuContext, Timestamps};
use raylume_sort::{
    DEAD_RAY_KEY, LIVE_RAY_KEY_MAX, RadixSorter, SortError, SortLen, SortOptions, key_mask,
    ray_sort_key, sort_pairs, sort_pairs_cpu,
};

/// splitmix64: a deterministic generator, so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as u32
    }
    fn keys(&mut self, n: usize) -> Vec<u32> {
        (0..n).map(|_| self.next_u32()).collect()
    }
}

fn indices(n: usize) -> Vec<u32> {
    (0..n as u32).collect()
}

/// Output order non-decreasing in the masked key, equal keys in increasing value (= index).
fn assert_sorted_stably(keys: &[u32], values: &[u32], key_bits: u32, what: &str) {
    let mask = key_mask(key_bits);
    for i in 1..keys.len() {
        let (a, b) = (keys[i - 1] & mask, keys[i] & mask);
        assert!(a <= b, "{what}: keys out of order at {i}: {a:#x} > {b:#x}");
        if a == b {
            assert!(
                values[i - 1] < values[i],
                "{what}: unstable at {i}: equal keys {a:#x} with values {} then {}",
                values[i - 1],
                values[i]
            );
        }
    }
}

/// Sorts `keys` (values = indices) with `sorter` and compares with the CPU reference.
fn check(ctx: &GpuContext, sorter: &RadixSorter, keys: &[u32], what: &str) {
    let values = indices(keys.len());
    let bits = sorter.plan().key_bits;
    let (k, v) = sorter
        .sort_pairs(ctx, keys, &values)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let (ek, ev) = sort_pairs_cpu(keys, &values, bits);
    if let Some(i) = k.iter().zip(&ek).position(|(a, b)| a != b) {
        panic!(
            "{what} (n = {}, plan {:?}): first key mismatch at {i}: gpu {:#x} cpu {:#x}",
            keys.len(),
            sorter.plan(),
            k[i],
            ek[i]
        );
    }
    assert!(v == ev, "{what}: values differ from the stable CPU sort");
    assert_sorted_stably(&k, &v, bits, what);
}

/// Lengths around the tile size and the odd ones.
fn lengths(tile: usize) -> Vec<usize> {
    vec![1, 2, 3, 31, tile - 1, tile, tile + 1, 3 * tile + 17, 20_011]
}

/// Every distribution at every length, for one set of options.
fn check_options(ctx: &GpuContext, opts: SortOptions, what: &str) {
    let mut rng = Rng(0x5EED ^ u64::from(opts.radix_bits));
    let sorter = RadixSorter::new(ctx, 40_000, opts).unwrap();
    let tile = sorter.plan().tile as usize;
    for n in lengths(tile) {
        let random30: Vec<u32> = rng.keys(n).iter().map(|k| k & 0x3FFF_FFFF).collect();
        check(
            ctx,
            &sorter,
            &random30,
            &format!("{what}: random 30-bit, n = {n}"),
        );
        check(
            ctx,
            &sorter,
            &rng.keys(n),
            &format!("{what}: random 32-bit, n = {n}"),
        );
    }
    let n = 20_011;
    let mut sorted: Vec<u32> = rng.keys(n);
    sorted.sort_unstable_by_key(|k| k & key_mask(opts.key_bits));
    let reversed: Vec<u32> = sorted.iter().rev().copied().collect();
    let cases: Vec<(&str, Vec<u32>)> = vec![
        ("all equal", vec![0x1234_5678; n]),
        ("all zero", vec![0; n]),
        ("all ones", vec![u32::MAX; n]),
        ("already sorted", sorted),
        ("reversed", reversed),
        (
            "three distinct",
            rng.keys(n).iter().map(|k| k % 3).collect(),
        ),
        // Each key has exactly one of the 32 bits set: every digit of every pass is used.
        (
            "single bits",
            rng.keys(n).iter().map(|k| 1 << (k % 32)).collect(),
        ),
        // Equal low 30 bits, different upper bits: must keep input order under a 30-bit sort.
        (
            "upper bits only",
            rng.keys(n)
                .iter()
                .map(|k| (k & 0xC000_0000) | 0x155)
                .collect(),
        ),
    ];
    for (name, keys) in cases {
        check(ctx, &sorter, &keys, &format!("{what}: {name}"));
    }
}

#[test]
fn default_options_match_cpu() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("default_options_match_cpu") else {
        return;
    };
    check_options(ctx, SortOptions::ray_keys(), "default");
}

#[test]
fn shared_memory_path_matches_cpu() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("shared_memory_path_matches_cpu") else {
        return;
    };
    let opts = SortOptions::ray_keys().with_subgroups(false);
    assert!(!RadixSorter::new(ctx, 1, opts).unwrap().plan().subgroups);
    check_options(ctx, opts, "no subgroups");
}

#[test]
fn subgroup_path_is_used_when_available() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("subgroup_path_is_used_when_available")
    else {
        return;
    };
    let plan = *RadixSorter::new(ctx, 1, SortOptions::ray_keys())
        .unwrap()
        .plan();
    assert_eq!(plan.subgroups, ctx.has_subgroups(), "{plan:?}");
    if raylume_gpu::testing::gpu_required() && ctx.info.is_software {
        // lavapipe has subgroups (of 8): CI must exercise the subgroup kernels.
        assert!(plan.subgroups, "lavapipe should run the subgroup path");
    }
}

#[test]
fn other_workgroup_sizes_and_digit_widths_match_cpu() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("other_workgroup_sizes_and_digit_widths_match_cpu")
    else {
        return;
    };
    for sg in [true, false] {
        let base = SortOptions::ray_keys().with_subgroups(sg);
        let variants = [
            ("wg 64 x 4", base.with_tile(64, 4)),
            // Not a power of two, not a multiple of lavapipe's subgroup size of 8.
            ("wg 100 x 3", base.with_tile(100, 3)),
            // 10-bit digits: 3 passes, so the final copy kernel runs; 32 threads < 1024 digits.
            ("10-bit digits", base.with_radix_bits(10).with_tile(32, 8)),
            (
                "full 32-bit keys, 4-bit digits",
                SortOptions::full_keys()
                    .with_subgroups(sg)
                    .with_radix_bits(4)
                    .with_tile(64, 8),
            ),
            ("7-bit keys", base.with_key_bits(7).with_tile(64, 8)),
            // The four-word ballot path of 64/128-lane adapters, run on narrower subgroups.
            (
                "wide ballot masks",
                base.with_wide_ballot_masks(true).with_tile(100, 3),
            ),
        ];
        for (name, opts) in variants {
            check_options(ctx, opts, &format!("{name}, subgroups {sg}"));
        }
    }
}

#[test]
fn million_pairs_match_cpu() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("million_pairs_match_cpu") else {
        return;
    };
    let n = (1 << 20) + 123;
    let keys = Rng(7).keys(n);
    for sg in [true, false] {
        let sorter =
            RadixSorter::new(ctx, n as u32, SortOptions::ray_keys().with_subgroups(sg)).unwrap();
        check(ctx, &sorter, &keys, &format!("1M, subgroups {sg}"));
    }
}

/// The adapter's largest length, capped at 32M pairs: lavapipe's true maximum
/// (`max_storage_buffer_binding_size / 4` = 128 MiB / 4), ~15 s here with its CPU reference.
/// Larger adapters are capped (an H100 allows 512M pairs; its CPU reference alone would take
/// a minute); there nothing in the kernels depends on the length except u32 index arithmetic
/// below it (`RadixSorter::new` rejects lengths where `tile * TILE + TILE` or the tile counters
/// would overflow) and the tile grid, whose second dimension `grid_2d_*` exercise. The bench
/// sorted the H100's maximum, 536,870,911 pairs on a 3-row grid, in 34 ms (output checked
/// sorted).
#[test]
fn large_length_matches_cpu() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("large_length_matches_cpu") else {
        return;
    };
    let n = ((ctx.max_binding_bytes() / 4) as usize).min(32 << 20);
    let keys: Vec<u32> = Rng(11).keys(n);
    let sorter = RadixSorter::new(ctx, n as u32, SortOptions::ray_keys()).unwrap();
    check(ctx, &sorter, &keys, "largest length");
}

#[test]
fn grid_2d_small_rows_match_cpu() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("grid_2d_small_rows_match_cpu") else {
        return;
    };
    for sg in [true, false] {
        // 7 workgroups per row: 22 tiles make 4 rows, the last one partly empty.
        let opts = SortOptions::ray_keys()
            .with_subgroups(sg)
            .with_tile(64, 4)
            .with_max_grid_x(7);
        let sorter = RadixSorter::new(ctx, 30_000, opts).unwrap();
        let n = 21 * 256 + 5;
        check(
            ctx,
            &sorter,
            &Rng(3).keys(n),
            &format!("grid of 7 per row, subgroups {sg}"),
        );
    }
}

/// Just over the adapter's real dispatch limit (65535 workgroups per dimension on every
/// adapter seen): tiles of 32 keys make 65536 tiles, the second row holding one.
#[test]
fn grid_2d_past_the_dispatch_limit_matches_cpu() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("grid_2d_past_the_dispatch_limit_matches_cpu")
    else {
        return;
    };
    let limit = ctx.limits.max_compute_workgroups_per_dimension as usize;
    let opts = SortOptions::ray_keys().with_tile(32, 1);
    let n = limit * 32 + 1;
    let sorter = RadixSorter::new(ctx, n as u32, opts).unwrap();
    assert_eq!(sorter.plan().max_grid_x as usize, limit);
    check(
        ctx,
        &sorter,
        &Rng(5).keys(n),
        "just past the dispatch limit",
    );
}

#[test]
fn lengths_zero_one_two_via_sort_pairs() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("lengths_zero_one_two_via_sort_pairs")
    else {
        return;
    };
    assert_eq!(sort_pairs(ctx, &[], &[]).unwrap(), (vec![], vec![]));
    assert_eq!(sort_pairs(ctx, &[9], &[4]).unwrap(), (vec![9], vec![4]));
    assert_eq!(
        sort_pairs(ctx, &[9, 3], &[4, 5]).unwrap(),
        (vec![3, 9], vec![5, 4])
    );
    // Equal in the low 30 bits: order kept.
    assert_eq!(
        sort_pairs(ctx, &[0x4000_0003, 3], &[1, 2]).unwrap(),
        (vec![0x4000_0003, 3], vec![1, 2])
    );
}

#[test]
fn dead_rays_sort_last() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("dead_rays_sort_last") else {
        return;
    };
    let mut rng = Rng(99);
    let (lo, ext) = (glam::Vec3::ZERO, glam::Vec3::ONE);
    let n = 50_000;
    let keys: Vec<u32> = (0..n)
        .map(|i| match rng.next_u32() % 4 {
            0 => DEAD_RAY_KEY,
            // The corner cell pair that would be all ones: capped at LIVE_RAY_KEY_MAX.
            1 => ray_sort_key(glam::Vec3::splat(2.0), glam::Vec3::ONE, lo, ext),
            _ => {
                let u = |r: &mut Rng| r.next_u32() as f32 / u32::MAX as f32;
                let o = glam::Vec3::new(u(&mut rng), u(&mut rng), u(&mut rng));
                let d = glam::Vec3::new(u(&mut rng), u(&mut rng), u(&mut rng)) * 2.0 - 1.0;
                ray_sort_key(o, d, lo, ext) ^ (i as u32 & 1) // a few odd keys too
            }
        })
        .collect();
    assert!(keys.contains(&LIVE_RAY_KEY_MAX));
    let values = indices(n);
    for sg in [true, false] {
        let sorter =
            RadixSorter::new(ctx, n as u32, SortOptions::ray_keys().with_subgroups(sg)).unwrap();
        let (k, v) = sorter.sort_pairs(ctx, &keys, &values).unwrap();
        let dead = keys.iter().filter(|&&k| k == DEAD_RAY_KEY).count();
        let live = n - dead;
        assert!(
            k[..live].iter().all(|&k| k != DEAD_RAY_KEY),
            "a dead ray before a live one"
        );
        assert!(k[live..].iter().all(|&k| k == DEAD_RAY_KEY));
        assert!(
            v[live..].windows(2).all(|w| w[0] < w[1]),
            "dead rays reordered"
        );
        assert_sorted_stably(&k, &v, 30, "dead rays");
    }
}

/// Sorts `count` pairs whose count lives in a GPU buffer; the rest of the buffers is untouched.
fn sort_indirect(
    ctx: &GpuContext,
    sorter: &RadixSorter,
    keys: &[u32],
    count: u32,
) -> (Vec<u32>, Vec<u32>) {
    let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    let values = indices(keys.len());
    let kbuf = ctx.storage_buffer("keys", keys, usage).unwrap();
    let vbuf = ctx.storage_buffer("values", &values, usage).unwrap();
    // The count at byte offset 8 of a small counters buffer, as a tracer would keep it.
    let counters = ctx
        .storage_buffer("counters", &[111u32, 222, count, 333], usage)
        .unwrap();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let len = SortLen::Indirect {
        count_buffer: &counters,
        offset: 8,
    };
    sorter
        .encode(&mut encoder, &kbuf, &vbuf, len, None)
        .unwrap();
    ctx.queue.submit([encoder.finish()]);
    (
        ctx.read_buffer(&kbuf, keys.len()).unwrap(),
        ctx.read_buffer(&vbuf, keys.len()).unwrap(),
    )
}

#[test]
fn indirect_length_sorts_only_the_counted_prefix() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("indirect_length_sorts_only_the_counted_prefix")
    else {
        return;
    };
    let n = 30_000;
    let keys = Rng(21).keys(n);
    for sg in [true, false] {
        for opts in [
            SortOptions::ray_keys(),
            SortOptions::ray_keys().with_radix_bits(10),
        ] {
            let opts = opts.with_subgroups(sg);
            let sorter = RadixSorter::new(ctx, n as u32, opts).unwrap();
            for count in [0, 1, 7_777, n as u32] {
                let c = count as usize;
                let (k, v) = sort_indirect(ctx, &sorter, &keys, count);
                let (ek, ev) = sort_pairs_cpu(&keys[..c], &indices(c), 30);
                assert_eq!(k[..c], ek[..], "count {count}, {opts:?}");
                assert_eq!(v[..c], ev[..], "count {count}, {opts:?}");
                assert_eq!(
                    k[c..],
                    keys[c..],
                    "count {count}: the tail must stay untouched"
                );
                assert_eq!(v[c..], indices(n)[c..]);
            }
        }
    }
    // A count above the sorter's capacity is clamped to it.
    let sorter = RadixSorter::new(ctx, 1000, SortOptions::ray_keys()).unwrap();
    let (k, _) = sort_indirect(ctx, &sorter, &keys[..1000], 5_000_000);
    assert_eq!(k, sort_pairs_cpu(&keys[..1000], &indices(1000), 30).0);
}

#[test]
fn several_sorts_in_one_encoder_with_timestamps() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("several_sorts_in_one_encoder_with_timestamps")
    else {
        return;
    };
    let sorter = RadixSorter::new(ctx, 10_000, SortOptions::ray_keys()).unwrap();
    let mut ts = Timestamps::new(ctx, 2);
    let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    let mut rng = Rng(8);
    let a = rng.keys(10_000);
    let b = rng.keys(3_000);
    let (ka, va) = (
        ctx.storage_buffer("a keys", &a, usage).unwrap(),
        ctx.storage_buffer("a values", &indices(a.len()), usage)
            .unwrap(),
    );
    let (kb, vb) = (
        ctx.storage_buffer("b keys", &b, usage).unwrap(),
        ctx.storage_buffer("b values", &indices(b.len()), usage)
            .unwrap(),
    );
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    sorter
        .encode(&mut encoder, &ka, &va, SortLen::Fixed(10_000), ts.as_mut())
        .unwrap();
    sorter
        .encode(&mut encoder, &kb, &vb, SortLen::Fixed(3_000), ts.as_mut())
        .unwrap();
    if let Some(ts) = &ts {
        ts.resolve(&mut encoder);
    }
    ctx.queue.submit([encoder.finish()]);
    let ga = ctx.read_buffer::<u32>(&ka, a.len()).unwrap();
    let gb = ctx.read_buffer::<u32>(&kb, b.len()).unwrap();
    assert_eq!(ga, sort_pairs_cpu(&a, &indices(a.len()), 30).0);
    assert_eq!(gb, sort_pairs_cpu(&b, &indices(b.len()), 30).0);
    if let Some(ts) = &mut ts {
        let times = ts.read(ctx).unwrap();
        assert_eq!(times.len(), 2);
        assert!(times.iter().all(|(label, _)| *label == "sort_keys"));
    }
}

#[test]
fn misuse_gives_typed_errors() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("misuse_gives_typed_errors") else {
        return;
    };
    let sorter = RadixSorter::new(ctx, 100, SortOptions::ray_keys()).unwrap();
    let keys = vec![1u32; 101];
    assert!(matches!(
        sorter.sort_pairs(ctx, &keys, &keys),
        Err(SortError::TooLong {
            len: 101,
            max_len: 100
        })
    ));
    assert!(matches!(
        sorter.sort_pairs(ctx, &keys[..3], &keys[..2]),
        Err(SortError::LengthMismatch { keys: 3, values: 2 })
    ));
    for bad in [
        SortOptions::ray_keys().with_key_bits(0),
        SortOptions::ray_keys().with_key_bits(33),
        SortOptions::ray_keys().with_radix_bits(3),
        SortOptions::ray_keys().with_radix_bits(11),
        SortOptions::ray_keys().with_tile(0, 4),
        SortOptions::ray_keys().with_tile(64, 0),
        SortOptions::ray_keys().with_tile(4096, 16),
    ] {
        let r = RadixSorter::new(ctx, 10, bad);
        assert!(
            matches!(r, Err(SortError::InvalidOptions(_))),
            "{bad:?}: {r:?}"
        );
    }
    // Over the adapter's binding size.
    let max = (ctx.max_binding_bytes() / 4) as u32;
    assert!(matches!(
        RadixSorter::new(ctx, max.saturating_add(1), SortOptions::ray_keys()),
        Err(SortError::Gpu(raylume_gpu::GpuError::TooLarge { .. }))
    ));
    // Exactly the maximum is accepted (the scratch buffers fit one binding each).
    let at_max = RadixSorter::new(ctx, max, SortOptions::ray_keys()).unwrap();
    assert_eq!(at_max.max_len(), max);
    // ... and its full-size scratch buffers bind (a sort of a few pairs binds them whole).
    let (k, v) = at_max.sort_pairs(ctx, &[3, 1, 2], &[0, 1, 2]).unwrap();
    assert_eq!((k, v), (vec![1, 2, 3], vec![1, 2, 0]));
    drop(at_max);
    // Buffers: too small, no STORAGE, count without COPY_SRC.
    let small = ctx
        .storage_buffer("small", &[0u32; 8], wgpu::BufferUsages::empty())
        .unwrap();
    let big = ctx
        .storage_buffer("big", &[0u32; 100], wgpu::BufferUsages::empty())
        .unwrap();
    let not_storage = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 400,
        usage: wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let r = sorter.encode(&mut enc, &small, &big, SortLen::Fixed(50), None);
    assert!(
        matches!(r, Err(SortError::BadBuffer { which: "keys", .. })),
        "{r:?}"
    );
    let r = sorter.encode(&mut enc, &big, &not_storage, SortLen::Fixed(50), None);
    assert!(
        matches!(
            r,
            Err(SortError::BadBuffer {
                which: "values",
                ..
            })
        ),
        "{r:?}"
    );
    let indirect = SortLen::Indirect {
        count_buffer: &small,
        offset: 0,
    };
    // Indirect needs max_len words: `small` is too small for keys.
    let r = sorter.encode(&mut enc, &small, &big, indirect, None);
    assert!(
        matches!(r, Err(SortError::BadBuffer { which: "keys", .. })),
        "{r:?}"
    );
    let r = sorter.encode(&mut enc, &big, &big, indirect, None);
    assert!(
        matches!(r, Err(SortError::BadBuffer { which: "count", .. })),
        "{r:?}"
    );
}
