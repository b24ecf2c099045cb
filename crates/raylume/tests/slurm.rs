//! The Slurm job array of `examples/slurm/submit.sh`, run for real (issue 16): a 4-part array
//! of a small scene and the dependent merge job, on the single-node cluster `.ci/run` starts
//! (`../shared/slurm/`); the merged image must equal a single render within
//! `raylume::merge_bound`. Skipped (saying so) where no cluster answers, unless
//! `RAYLUME_REQUIRE_SLURM=1` (CI), where that is a failure.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// True when `sinfo` reaches a cluster with an idle or mixed node.
fn cluster_up() -> bool {
    Command::new("sinfo")
        .args(["-h", "-o", "%t"])
        .output()
        .is_ok_and(|o| {
            o.status.success() && {
                let s = String::from_utf8_lossy(&o.stdout);
                s.lines()
                    .any(|l| matches!(l.trim(), "idle" | "mix" | "alloc"))
            }
        })
}

#[test]
fn a_slurm_job_array_renders_the_parts_and_merges_them() {
    if !cluster_up() {
        assert!(
            std::env::var("RAYLUME_REQUIRE_SLURM").as_deref() != Ok("1"),
            "RAYLUME_REQUIRE_SLURM=1 but no Slurm cluster answers `sinfo` (start one: \
             ../shared/slurm/start.sh, then source its env.sh)"
        );
        eprintln!(
            "SKIPPED: no Slurm cluster answers `sinfo` (RAYLUME_REQUIRE_SLURM=1 requires one)"
        );
        return;
    }
    let dir = std::env::temp_dir().join(format!("raylume-slurm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let render = common::render_exe();
    let bin = render.parent().unwrap();
    let flags = [
        "--backend",
        "cpu",
        "--size",
        "16x12",
        "--spp",
        "8",
        "--bounces",
        "3",
    ];
    let merged = dir.join("merged.exr");
    let out = Command::new(repo().join("examples/slurm/submit.sh"))
        .arg(repo().join("scenes/cornell-box.toml"))
        .arg(&merged)
        .arg("4")
        .args(flags)
        .env("RAYLUME_BIN", bin)
        .env("PARTS_DIR", dir.join("parts"))
        .output()
        .expect("run submit.sh");
    assert!(
        out.status.success(),
        "submit.sh: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ids = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let jobs: Vec<&str> = ids.split_whitespace().collect();
    assert_eq!(jobs.len(), 2, "submit.sh printed `{ids}`");
    // No accounting on the test cluster: poll the queue until both jobs have left it.
    let start = Instant::now();
    loop {
        let q = Command::new("squeue")
            .args(["-h", "-j", &jobs.join(",")])
            .output()
            .expect("squeue");
        if String::from_utf8_lossy(&q.stdout).trim().is_empty() {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(180),
            "the jobs did not finish in 180 s: {}",
            String::from_utf8_lossy(&q.stdout)
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    let log =
        |name: &str| std::fs::read_to_string(dir.join("parts").join(name)).unwrap_or_default();
    assert!(
        merged.exists(),
        "no merged image; merge log: {}; part 1 log: {}",
        log("merge.log"),
        log("part-1.log")
    );
    for i in 1..=4 {
        assert!(dir.join(format!("parts/part-{i}.exr")).exists(), "part {i}");
    }
    // The single render of all the samples, the same way.
    let whole = dir.join("whole.exr");
    let o = Command::new(&render)
        .current_dir(repo())
        .arg("scenes/cornell-box.toml")
        .args(flags)
        .args(["-q", "-o"])
        .arg(&whole)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = image::open(&merged).unwrap().into_rgb32f();
    let b = image::open(&whole).unwrap().into_rgb32f();
    let bound = raylume::merge_bound(8);
    let pixels = |im: &image::Rgb32FImage| im.pixels().map(|p| p.0).collect::<Vec<_>>();
    let worst = raylume::worst_relative_difference(&pixels(&a), &pixels(&b));
    assert!(
        worst <= bound,
        "merged vs single render: {worst:.3e} > {bound:.3e}"
    );
    assert!(
        b.pixels().any(|p| p[0] > 0.0),
        "a black image tests nothing"
    );
    eprintln!(
        "slurm: 4 parts + merge in {:.1} s, worst relative difference {worst:.2e} (bound {bound:.2e})",
        start.elapsed().as_secs_f64()
    );
    std::fs::remove_dir_all(&dir).ok();
}
