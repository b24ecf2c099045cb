//! [`SortOptions`] (what the caller asks for) and [`SortPlan`] (what runs on this adapter).

use raylume_gpu::GpuContext;

use crate::SortError;

/// How a [`RadixSorter`](crate::RadixSorter) sorts. A `Copy` struct with `const fn` presets;
/// [`SortOptions::default`] is [`SortOptions::ray_keys`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SortOptions {
    /// Low bits of each key that decide the order, 1..=32 (bits above are carried along but
    /// ignored). Default 30: ray sort keys (see [`crate::morton`]).
    pub key_bits: u32,
    /// Bits per radix digit, 4..=10: `ceil(key_bits / radix_bits)` passes, each reading and
    /// writing every pair once. Default 8 (4 passes for 30-bit keys; why 8 rather than 10: see
    /// the crate docs).
    pub radix_bits: u32,
    /// Threads per workgroup. `None` picks the largest of 256, 128, 64, 32 whose shared memory
    /// fits the adapter (256 on an H100; lavapipe's 32 KiB with its 8-wide subgroups takes 128;
    /// on the H100, 128 and 512 threads were 10-40% slower than 256).
    pub workgroup_size: Option<u32>,
    /// Keys per thread, 1..=32; a tile is `workgroup_size * items_per_thread` keys (at most
    /// 65536). Default 12: on an H100 (256 threads, 16M pairs) 12 took 1.14 ms, 8 took 1.37,
    /// 10 took 1.23, 14 took 1.57 and 16 took 1.45 (`benches/sort.rs`, 2026-11-23).
    pub items_per_thread: u32,
    /// Use subgroup operations (ballots, shuffles, subgroup scans) when the device has
    /// `Features::SUBGROUP`. `false` forces the shared-memory path. Default true.
    pub use_subgroups: bool,
    /// Cap on workgroups per row of the tile grid (2D dispatches beyond it). `None` = the
    /// adapter's `max_compute_workgroups_per_dimension`. Tests set it low to exercise the grid.
    pub max_grid_x: Option<u32>,
    /// Use four-word ballot masks (the path of adapters with 64- or 128-lane subgroups) even
    /// when every subgroup has at most 32 lanes, where one word suffices. For tests. Default
    /// false.
    pub wide_ballot_masks: bool,
    /// With timestamps, time every kernel in its own compute pass (labelled `sort_setup`,
    /// `sort_upsweep`, `sort_scan`, `sort_downsweep`, `sort_copy`) rather than the whole sort
    /// as one `sort_keys` pass. For profiling. Default false.
    pub stage_timestamps: bool,
}

impl Default for SortOptions {
    fn default() -> Self {
        Self::ray_keys()
    }
}

impl SortOptions {
    /// 30-bit ray sort keys, 8-bit digits (4 passes), 12 keys per thread, subgroups when present.
    pub const fn ray_keys() -> Self {
        Self {
            key_bits: 30,
            radix_bits: 8,
            workgroup_size: None,
            items_per_thread: 12,
            use_subgroups: true,
            max_grid_x: None,
            wide_ballot_masks: false,
            stage_timestamps: false,
        }
    }

    /// Full 32-bit keys (4 passes of 8 bits).
    pub const fn full_keys() -> Self {
        Self {
            key_bits: 32,
            ..Self::ray_keys()
        }
    }

    /// These options with `key_bits` changed.
    pub const fn with_key_bits(mut self, key_bits: u32) -> Self {
        self.key_bits = key_bits;
        self
    }

    /// These options with `radix_bits` changed.
    pub const fn with_radix_bits(mut self, radix_bits: u32) -> Self {
        self.radix_bits = radix_bits;
        self
    }

    /// These options with a fixed workgroup size and keys per thread.
    pub const fn with_tile(mut self, workgroup_size: u32, items_per_thread: u32) -> Self {
        self.workgroup_size = Some(workgroup_size);
        self.items_per_thread = items_per_thread;
        self
    }

    /// These options with subgroup operations allowed or not.
    pub const fn with_subgroups(mut self, use_subgroups: bool) -> Self {
        self.use_subgroups = use_subgroups;
        self
    }

    /// These options with four-word ballot masks forced (or not).
    pub const fn with_wide_ballot_masks(mut self, wide: bool) -> Self {
        self.wide_ballot_masks = wide;
        self
    }

    /// These options with one timestamped pass per kernel (or not).
    pub const fn with_stage_timestamps(mut self, on: bool) -> Self {
        self.stage_timestamps = on;
        self
    }

    /// These options with at most `x` workgroups per row of the tile grid.
    pub const fn with_max_grid_x(mut self, x: u32) -> Self {
        self.max_grid_x = Some(x);
        self
    }
}

/// What actually runs: the options resolved against one adapter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SortPlan {
    pub key_bits: u32,
    pub radix_bits: u32,
    /// 1 << radix_bits.
    pub radix: u32,
    /// ceil(key_bits / radix_bits).
    pub passes: u32,
    pub workgroup_size: u32,
    pub items_per_thread: u32,
    /// workgroup_size * items_per_thread.
    pub tile: u32,
    /// Whether the subgroup kernels run.
    pub subgroups: bool,
    /// Most subgroups one workgroup can have: ceil(workgroup_size / smallest subgroup size).
    pub max_subgroups: u32,
    /// Ballot masks of four words (subgroups of up to 128 lanes) rather than one (up to 32).
    pub wide_ballot_masks: bool,
    /// One timestamped pass per kernel.
    pub stage_timestamps: bool,
    /// Tile counts per thread in `sort_scan`.
    pub scan_items: u32,
    pub max_grid_x: u32,
    /// Workgroup memory of the largest stage, in bytes.
    pub shared_bytes: u32,
}

impl SortPlan {
    /// Resolves `opts` for `ctx`'s adapter, or says what does not fit.
    pub fn new(ctx: &GpuContext, opts: &SortOptions) -> Result<Self, SortError> {
        let bad = |m: String| Err(SortError::InvalidOptions(m));
        if !(1..=32).contains(&opts.key_bits) {
            return bad(format!("key_bits = {} (allowed 1..=32)", opts.key_bits));
        }
        if !(4..=10).contains(&opts.radix_bits) {
            return bad(format!("radix_bits = {} (allowed 4..=10)", opts.radix_bits));
        }
        if !(1..=32).contains(&opts.items_per_thread) {
            return bad(format!(
                "items_per_thread = {} (allowed 1..=32)",
                opts.items_per_thread
            ));
        }
        let limits = &ctx.limits;
        let info = ctx.adapter.get_info();
        let subgroups = opts.use_subgroups
            && ctx.has_subgroups()
            && info.subgroup_min_size >= 1
            && info.subgroup_max_size <= 128;
        let min_sg = info.subgroup_min_size.max(1);
        let max_wg = limits
            .max_compute_invocations_per_workgroup
            .min(limits.max_compute_workgroup_size_x);
        let grid_limit = limits.max_compute_workgroups_per_dimension;
        let max_grid_x = opts.max_grid_x.unwrap_or(grid_limit).clamp(1, grid_limit);

        let make = |wg: u32| -> SortPlan {
            let radix = 1u32 << opts.radix_bits;
            let tile = wg * opts.items_per_thread;
            let max_subgroups = if subgroups { wg.div_ceil(min_sg) } else { 1 };
            let words = if subgroups {
                // lanes + s_base + s_sg_hist + s_stage + s_count (the downsweep, the largest).
                max_subgroups + radix + max_subgroups * radix + tile + radix
            } else {
                // s_scan + s_base + s_stage + s_first.
                wg + radix + tile + radix
            };
            SortPlan {
                key_bits: opts.key_bits,
                radix_bits: opts.radix_bits,
                radix,
                passes: opts.key_bits.div_ceil(opts.radix_bits),
                workgroup_size: wg,
                items_per_thread: opts.items_per_thread,
                tile,
                subgroups,
                max_subgroups,
                wide_ballot_masks: opts.wide_ballot_masks || info.subgroup_max_size > 32,
                stage_timestamps: opts.stage_timestamps,
                scan_items: 4,
                max_grid_x,
                shared_bytes: words * 4,
            }
        };
        let fits = |p: &SortPlan| {
            p.workgroup_size <= max_wg
                && p.tile <= 65536
                && p.shared_bytes <= limits.max_compute_workgroup_storage_size
        };
        match opts.workgroup_size {
            Some(wg) => {
                if wg == 0 {
                    return bad("workgroup_size = 0".into());
                }
                let p = make(wg);
                if fits(&p) {
                    Ok(p)
                } else {
                    bad(format!(
                        "workgroup_size {wg} x items_per_thread {} with {}-bit digits{} needs \
                         {} bytes of workgroup memory and a tile of {} keys; `{}` allows {} \
                         threads, {} bytes, and tiles are at most 65536 keys",
                        opts.items_per_thread,
                        opts.radix_bits,
                        if subgroups { " (subgroup path)" } else { "" },
                        p.shared_bytes,
                        p.tile,
                        info.name,
                        max_wg,
                        limits.max_compute_workgroup_storage_size
                    ))
                }
            }
            None => [256, 128, 64, 32]
                .into_iter()
                .map(make)
                .find(fits)
                .map_or_else(
                    || {
                        bad(format!(
                            "no workgroup size of 256, 128, 64 or 32 fits {}-bit digits with {} \
                             keys per thread in the {} bytes of workgroup memory of `{}`",
                            opts.radix_bits,
                            opts.items_per_thread,
                            limits.max_compute_workgroup_storage_size,
                            info.name
                        ))
                    },
                    Ok,
                ),
        }
    }
}
