//! The `render` example is the command users run: its flags, its `--stats` JSON and its error
//! paths. Cargo builds examples before integration tests, so the binary sits in
//! `target/<profile>/examples/` beside this test's `deps/` folder.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn run(args: &[&str]) -> Output {
    run_example(common::render_exe(), args)
}

/// The example `exe` with `args`, from the repository's root.
fn run_example(exe: PathBuf, args: &[&str]) -> Output {
    Command::new(&exe)
        .args(args)
        .current_dir(repo())
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap_or_else(|e| panic!("run {}: {e}", exe.display()))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("raylume-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every key the issue names is present, with values that follow from the flags and scene.
fn check_stats(v: &serde_json::Value, backend: &str) {
    assert_eq!(v["backend"], backend);
    assert!(v["adapter"].as_str().is_some_and(|s| !s.is_empty()));
    assert_eq!(v["width"], 24);
    assert_eq!(v["height"], 16);
    assert_eq!(v["spp"], 3);
    assert_eq!(v["max_bounces"], 2);
    assert_eq!(v["triangles"], 36);
    // Which preset and builder made the tree (issue 19: the stats did not say).
    assert_eq!(v["bvh_preset"], "quality");
    assert!(
        v["bvh_builder"]
            .as_str()
            .is_some_and(|b| b.starts_with("obvhs PLOC on the CPU")),
        "{}",
        v["bvh_builder"]
    );
    let features: Vec<&str> = v["features"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert!(
        features.contains(&"diffuse") && features.contains(&"emission"),
        "{features:?}"
    );
    assert!(
        !features.contains(&"glass"),
        "the Cornell box has no glass: {features:?}"
    );
    // Every camera ray is traced, and no path traces more than 1 + max_bounces rays.
    let rays = v["rays_traced"].as_u64().unwrap();
    let samples = 24 * 16 * 3;
    assert!(rays >= samples && rays <= samples * 3, "{rays}");
    let s = &v["seconds"];
    for k in ["load", "bvh", "upload", "trace", "sort", "post", "total"] {
        let t = s[k]
            .as_f64()
            .unwrap_or_else(|| panic!("seconds.{k} missing"));
        assert!(t >= 0.0, "seconds.{k} = {t}");
    }
    assert!(s["trace"].as_f64().unwrap() > 0.0);
    assert!(s["total"].as_f64().unwrap() >= s["trace"].as_f64().unwrap());
    let mrays = v["mrays_per_s"].as_f64().unwrap();
    let expect = rays as f64 / s["trace"].as_f64().unwrap() / 1e6;
    assert!(
        (mrays - expect).abs() <= 1e-9 * expect.max(1.0),
        "{mrays} vs {expect}"
    );
}

const SMALL: [&str; 8] = [
    "--size",
    "24x16",
    "--spp",
    "3",
    "--bounces",
    "2",
    "-q",
    "--seed",
];

#[test]
fn cpu_render_writes_png_and_stats() {
    let d = tmp("cpu");
    let (png, stats) = (d.join("out.png"), d.join("stats.json"));
    let mut args = vec![
        "scenes/cornell-box.toml",
        "-o",
        png.to_str().unwrap(),
        "--backend",
        "cpu",
    ];
    args.extend(SMALL);
    args.extend(["7", "--stats", stats.to_str().unwrap()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("on CPU"),
        "says which backend: {}",
        stderr(&o)
    );
    // It says which instruction-set level the paths ran at: the highest this CPU executes.
    assert!(
        stderr(&o).contains(&format!("threads, {}", raylume::CpuIsa::best().name())),
        "{}",
        stderr(&o)
    );
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (24, 16));
    check_stats(&json(&stats), "cpu");
}

#[test]
fn gpu_render_writes_exr_and_stats() {
    if raylume_gpu::testing::context_or_skip("gpu_render_writes_exr_and_stats").is_none() {
        return;
    }
    let d = tmp("gpu");
    let (exr, stats) = (d.join("out.exr"), d.join("stats.json"));
    let mut args = vec![
        "scenes/cornell-box.toml",
        "-o",
        exr.to_str().unwrap(),
        "--backend",
        "gpu",
    ];
    args.extend(SMALL);
    args.extend(["7", "--stats", stats.to_str().unwrap()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("on GPU"), "{}", stderr(&o));
    assert!(
        !stderr(&o).contains("target-cpu=native"),
        "no CPU build advice for a GPU render: {}",
        stderr(&o)
    );
    assert!(
        stderr(&o).contains("raylume: rendering scenes/cornell-box.toml: backend GPU ("),
        "the settings line names the GPU backend and its adapter: {}",
        stderr(&o)
    );
    let img = image::open(&exr).unwrap().into_rgb32f();
    assert_eq!(img.dimensions(), (24, 16));
    // Linear radiance: the light's own pixels exceed 1 (its emission is 17, 12, 4); a PNG
    // could not hold that.
    assert!(
        img.pixels().any(|p| p[0] > 1.0),
        "EXR keeps radiance above 1"
    );
    check_stats(&json(&stats), "gpu");
}

/// Runs a failing command and checks its message, its exit code and that no file was left.
fn check_failure(args: &[&str], out: &Path, message_parts: &[&str]) {
    let o = run(args);
    assert!(!o.status.success(), "should fail: {args:?}");
    let err = stderr(&o);
    for part in message_parts {
        assert!(err.contains(part), "message lacks `{part}`: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "{} left behind", out.display());
}

#[test]
fn missing_scene_file_is_named() {
    let out = tmp("missing").join("out.png");
    check_failure(
        &["scenes/no-such-scene.toml", "-o", out.to_str().unwrap()],
        &out,
        &["no-such-scene.toml"],
    );
}

#[test]
fn bad_flags_are_rejected() {
    let out = tmp("flags").join("out.png");
    let o = out.to_str().unwrap();
    check_failure(
        &["scenes/cornell-box.toml", "-o", o, "--frobnicate"],
        &out,
        &["--frobnicate"],
    );
    check_failure(
        &["scenes/cornell-box.toml", "-o", o, "--backend", "tpu"],
        &out,
        &["tpu"],
    );
    check_failure(
        &["scenes/cornell-box.toml", "-o", o, "--size", "12by12"],
        &out,
        &["12by12"],
    );
    check_failure(
        &["scenes/cornell-box.toml", "-o", o, "--spp", "-3"],
        &out,
        &["-3"],
    );
    check_failure(
        &["scenes/cornell-box.toml", "-o", o, "--reorder", "sometimes"],
        &out,
        &["sometimes"],
    );
    // A batch of no samples is refused (the library would take it as 1).
    check_failure(
        &["scenes/cornell-box.toml", "-o", o, "--batch-spp", "0"],
        &out,
        &["--batch-spp", "0 is not in 1.."],
    );
}

/// The `trace_rate` measuring tool names what is wrong with its input, in one line, and exits
/// with a failure: no panic and backtrace (it panicked on a scene file it could not load and
/// on a malformed `--size`).
#[test]
fn trace_rate_reports_bad_input_without_a_panic() {
    let trace_rate = |args: &[&str]| run_example(common::trace_rate_exe(), args);
    for (args, wanted) in [
        (
            &["scenes/no-such-scene.toml", "--backend", "cpu"][..],
            "no-such-scene.toml",
        ),
        (
            &[
                "scenes/cornell-box.toml",
                "--backend",
                "cpu",
                "--size",
                "12by12",
            ][..],
            "--size 12by12",
        ),
        (
            &[
                "scenes/cornell-box.toml",
                "--backend",
                "cpu",
                "--size",
                "0x8",
            ][..],
            "--size 0x8",
        ),
        (
            &[
                "scenes/cornell-box.toml",
                "--backend",
                "cpu",
                "--size",
                "2048x2048",
            ][..],
            "--size 2048x2048",
        ),
    ] {
        let o = trace_rate(args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(
            err.starts_with("trace_rate: ") && err.contains(wanted),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // And a small set still measures.
    let o = trace_rate(&[
        "scenes/cornell-box.toml",
        "--backend",
        "cpu",
        "--bvh",
        "wide",
        "--size",
        "8x8",
        "--repeat",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("| cpu | primary (64) |"));
}

#[test]
fn absurd_sizes_are_rejected_before_rendering() {
    let out = tmp("sizes").join("out.png");
    let o = out.to_str().unwrap();
    check_failure(
        &[
            "scenes/cornell-box.toml",
            "-o",
            o,
            "--size",
            "0x0",
            "--backend",
            "cpu",
        ],
        &out,
        &["0x0"],
    );
    check_failure(
        &[
            "scenes/cornell-box.toml",
            "-o",
            o,
            "--size",
            "100000x100000",
            "--backend",
            "cpu",
        ],
        &out,
        &["100000x100000", "too large"],
    );
    check_failure(
        &[
            "scenes/cornell-box.toml",
            "-o",
            o,
            "--spp",
            "0",
            "--backend",
            "cpu",
        ],
        &out,
        &["0 samples"],
    );
}

#[test]
fn unwritable_outputs_fail_before_rendering() {
    let d = tmp("unwritable");
    let missing_dir = d.join("no/such/folder/out.png");
    check_failure(
        &[
            "scenes/cornell-box.toml",
            "-o",
            missing_dir.to_str().unwrap(),
            "--backend",
            "cpu",
        ],
        &missing_dir,
        &["does not exist"],
    );
    let wrong_ext = d.join("out.bmp");
    check_failure(
        &[
            "scenes/cornell-box.toml",
            "-o",
            wrong_ext.to_str().unwrap(),
            "--backend",
            "cpu",
        ],
        &wrong_ext,
        &[".png or .exr"],
    );
    // The output path is an existing directory: the final rename fails, nothing is left
    // behind (no temporary file either).
    let dir_as_file = d.join("taken.png");
    std::fs::create_dir_all(&dir_as_file).unwrap();
    let o = run(&[
        "scenes/cornell-box.toml",
        "-o",
        dir_as_file.to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "8x8",
        "--spp",
        "1",
        "-q",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("taken.png"), "{}", stderr(&o));
    let leftovers: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("raylume-tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn invalid_scene_leaves_no_output() {
    let d = tmp("invalid");
    let scene = d.join("bad.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0.0, 1.0, nan]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 40.0\n\n\
         [materials.white]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\n\
         [[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"white\"\n",
    )
    .unwrap();
    let out = d.join("out.png");
    check_failure(
        &[
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--backend",
            "cpu",
        ],
        &out,
        &["bad.toml"],
    );
}

#[test]
fn estimator_flags_and_target_error_reach_the_stats_and_the_summary() {
    let d = tmp("target");
    let (png, stats) = (d.join("out.png"), d.join("stats.json"));
    let base = [
        "scenes/cornell-box.toml",
        "-o",
        png.to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "16x12",
        "--bounces",
        "2",
        "-q",
        "--stats",
        stats.to_str().unwrap(),
    ];
    // The defaults: NEE, the shuffled Sobol' sampler, roulette from segment 5, no target.
    let o = run(&[&base[..], &["--spp", "2"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("estimator nee, sampler sobol, roulette from 5"),
        "{}",
        stderr(&o)
    );
    let v = json(&stats);
    assert_eq!(
        (&v["estimator"], &v["sampler"], &v["russian_roulette"]),
        (
            &serde_json::json!("nee"),
            &serde_json::json!("sobol"),
            &serde_json::json!(5)
        )
    );
    assert!(v["target_error"].is_null() && v["estimated_error"].is_null());

    // Any estimate is below 1e9: the render stops after the second batch, the first with an
    // estimate, at 2 x 4 of the 64 spp allowed.
    let o = run(&[
        &base[..],
        &[
            "--spp",
            "64",
            "--batch-spp",
            "4",
            "--target-error",
            "1e9",
            "--estimator",
            "plain",
            "--sampler",
            "independent",
            "--rr-depth",
            "off",
        ],
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    for part in [
        "estimator plain, sampler independent, roulette off",
        "target error 1.000e9: reached at 8 of at most 64 spp (2 batches of 4 spp), estimated \
         relative MSE",
    ] {
        assert!(err.contains(part), "lacks `{part}`: {err}");
    }
    let v = json(&stats);
    assert_eq!(v["spp"], 8);
    assert_eq!(v["spp_cap"], 64);
    assert_eq!(v["batches"], 2);
    assert_eq!(v["target_reached"], true);
    assert!(v["estimated_error"].as_f64().is_some_and(|e| e < 1e9));
    assert!(v["russian_roulette"].is_null());

    for (flag, value, message) in [
        (
            "--target-error",
            "0",
            "target error 0: use a relative MSE above 0",
        ),
        ("--target-error", "lots", "lots"),
        ("--sampler", "sobolish", "unknown sampler `sobolish`"),
        (
            "--environment-guide",
            "sometimes",
            "`sometimes`: on, off or auto",
        ),
        (
            "--rr-depth",
            "never",
            "`never` is not a path segment number or `off`",
        ),
    ] {
        let out = d.join(format!("bad-{value}.png"));
        let mut args = base.to_vec();
        args[2] = out.to_str().unwrap();
        args.extend([flag, value]);
        check_failure(&args, &out, &[message]);
    }
}

/// An unlit scene: a diffuse sphere, no emitter, no environment.
const UNLIT: &str = "[camera]\nposition = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 40.0\n\n\
     [materials.white]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\n\
     [[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"white\"\n";

fn lines(s: &str) -> Vec<&str> {
    s.lines().collect()
}

#[test]
fn settings_line_comes_before_any_progress_and_names_the_backend() {
    let d = tmp("settings");
    let png = d.join("out.png");
    let o = run(&[
        "scenes/cornell-box.toml",
        "-o",
        png.to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "24x16",
        "--spp",
        "4",
        "--batch-spp",
        "2",
        "--bounces",
        "2",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let all = lines(&err);
    let settings = all
        .iter()
        .position(|l| l.starts_with("raylume: rendering "))
        .unwrap_or_else(|| panic!("no settings line: {err}"));
    for part in [
        "backend CPU (CPU, ",
        "size 24x16",
        "spp 4",
        "bounces 2",
        "batch 2 spp",
        "estimator nee",
        "sampler sobol",
        "roulette from segment 5",
        "reorder off",
        "lights 2 emissive triangles, 0 emissive spheres, no environment (picked by power)",
    ] {
        assert!(
            all[settings].contains(part),
            "lacks `{part}`: {}",
            all[settings]
        );
    }
    let first = all
        .iter()
        .position(|l| l.starts_with("raylume: first batch: 2 of 4 spp in "))
        .unwrap_or_else(|| panic!("no estimate after the first batch: {err}"));
    assert!(
        all[first].contains("estimated trace time "),
        "{}",
        all[first]
    );
    assert!(settings < first, "{err}");
    assert!(
        !all.iter()
            .take(settings)
            .any(|l| l.starts_with("raylume: ")),
        "nothing before the settings line but warnings: {err}"
    );
}

#[test]
fn piped_progress_prints_plain_lines() {
    let d = tmp("piped");
    let png = d.join("out.png");
    let o = Command::new(common::render_exe())
        .args([
            "scenes/cornell-box.toml",
            "-o",
            png.to_str().unwrap(),
            "--backend",
            "cpu",
            "--size",
            "32x32",
            "--spp",
            "8",
            "--batch-spp",
            "1",
            "--bounces",
            "2",
        ])
        .current_dir(repo())
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        // Every batch after the first prints a line (5 s apart by default).
        .env("RAYLUME_PROGRESS_SECS", "0")
        .output()
        .expect("run render");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let progress: Vec<&str> = lines(&err)
        .into_iter()
        .filter(|l| l.starts_with("raylume: progress "))
        .collect();
    assert_eq!(
        progress.len(),
        7,
        "one line per batch after the first: {err}"
    );
    assert!(
        progress[6].starts_with("raylume: progress 8/8 spp, "),
        "{err}"
    );
    assert!(
        !err.contains('\u{1b}'),
        "no escape codes when piped: {err:?}"
    );
    assert!(
        !err.contains('\r'),
        "no carriage returns when piped: {err:?}"
    );
}

#[test]
fn quiet_drops_progress_but_keeps_the_settings_line() {
    let d = tmp("quiet");
    let png = d.join("out.png");
    let mut args = vec![
        "scenes/cornell-box.toml",
        "-o",
        png.to_str().unwrap(),
        "--backend",
        "cpu",
    ];
    args.extend(SMALL);
    args.push("1");
    let o = run(&args);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("raylume: rendering "), "{err}");
    assert!(
        !err.contains("raylume: first batch") && !err.contains("raylume: progress"),
        "{err}"
    );
}

#[test]
fn version_prints_the_crate_version() {
    let o = run(&["--version"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(out.trim(), format!("render {}", env!("CARGO_PKG_VERSION")));
}

#[test]
fn unlit_scene_warns_and_lit_scene_does_not() {
    let d = tmp("unlit");
    let scene = d.join("unlit.toml");
    std::fs::write(&scene, UNLIT).unwrap();
    let (png, stats) = (d.join("out.png"), d.join("stats.json"));
    let mut args = vec![
        scene.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--backend",
        "cpu",
        "--stats",
        stats.to_str().unwrap(),
    ];
    args.extend(SMALL);
    args.push("1");
    let o = run(&args);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warnings: Vec<&str> = lines(&err)
        .into_iter()
        .filter(|l| l.starts_with("warning: "))
        .collect();
    assert_eq!(
        warnings,
        [format!("warning: {}", raylume::NO_LIGHT_WARNING)],
        "{err}"
    );
    let settings = err.find("raylume: rendering ").expect("settings line");
    assert!(
        err.find("warning: ").unwrap() < settings,
        "warned before rendering: {err}"
    );
    assert!(err.contains("lights none"), "{err}");
    let v = json(&stats);
    assert_eq!(
        v["warnings"],
        serde_json::json!([raylume::NO_LIGHT_WARNING])
    );
    assert_eq!(
        v["lights"],
        serde_json::json!({"triangles": 0, "spheres": 0, "environment": false, "selection": "power"})
    );

    args[0] = "scenes/cornell-box.toml";
    let o = run(&args);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("warning:"), "{err}");
    let v = json(&stats);
    assert_eq!(v["warnings"], serde_json::json!([]));
    assert_eq!(v["lights"]["triangles"], 2);
}

/// Without `XDG_RUNTIME_DIR`, the Vulkan loader would print `error: XDG_RUNTIME_DIR is invalid
/// or not set` when the GPU instance is created (`auto` creates one to look for a GPU).
#[test]
fn no_vulkan_loader_noise_without_xdg_runtime_dir() {
    let d = tmp("xdg");
    let png = d.join("out.png");
    let mut args = vec![
        "scenes/cornell-box.toml",
        "-o",
        png.to_str().unwrap(),
        "--backend",
        "auto",
    ];
    args.extend(SMALL);
    args.push("1");
    let o = Command::new(common::render_exe())
        .args(&args)
        .current_dir(repo())
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .expect("run render");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("XDG_RUNTIME_DIR"), "{err}");
    assert!(!err.contains("error"), "{err}");
}

/// `render --part 1/2` and `--part 2/2`, merged by `merge`, give `render`'s image of all the
/// samples within `raylume::merge_bound`; a missing part is refused and nothing written.
#[test]
fn parts_and_merge_commands_make_the_whole_render() {
    let dir = tmp("parts");
    let base = [
        "scenes/cornell-box.toml",
        "--backend",
        "cpu",
        "--size",
        "12x10",
        "--spp",
        "4",
        "--bounces",
        "3",
        "-q",
    ];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    fn s(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    let whole = dir.join("whole.exr");
    let o = run(&s(&with(&["-o", whole.to_str().unwrap()])));
    assert!(o.status.success(), "{}", stderr(&o));
    let mut parts = Vec::new();
    for i in 1..=2 {
        let p = dir.join(format!("part-{i}.exr"));
        let o = run(&s(&with(&[
            "--part",
            &format!("{i}/2"),
            "-o",
            p.to_str().unwrap(),
        ])));
        assert!(o.status.success(), "{}", stderr(&o));
        parts.push(p);
    }
    let merged = dir.join("merged.exr");
    let merge = |out: &Path, parts: &[&Path]| {
        Command::new(common::merge_exe())
            .arg("-o")
            .arg(out)
            .args(parts)
            .output()
            .expect("run merge")
    };
    let o = merge(&merged, &[&parts[1], &parts[0]]);
    assert!(o.status.success(), "{}", stderr(&o));
    let a = image::open(&merged).unwrap().into_rgb32f();
    let b = image::open(&whole).unwrap().into_rgb32f();
    let bound = raylume::merge_bound(4);
    let pixels = |im: &image::Rgb32FImage| im.pixels().map(|p| p.0).collect::<Vec<_>>();
    let worst = raylume::worst_relative_difference(&pixels(&a), &pixels(&b));
    assert!(worst <= bound, "merged vs whole: {worst:.3e} > {bound:.3e}");
    // `compare --merge-bound` checks the same bound (what the two-GPU run of issue 17 uses):
    // the merge passes; a render of another seed fails, the worst difference named; an image
    // passes against itself at any bound.
    let compare = |test: &Path, reference: &Path, spp: &str| {
        Command::new(common::compare_exe())
            .arg(test)
            .arg(reference)
            .args(["--merge-bound", spp, "--blocks", "0"])
            .output()
            .expect("run compare")
    };
    let o = compare(&merged, &whole, "4");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("within the merge bound"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let other = dir.join("other-seed.exr");
    let o = run(&s(&with(&["--seed", "7", "-o", other.to_str().unwrap()])));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = compare(&other, &whole, "4");
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("past the merge bound"),
        "{}",
        stderr(&o)
    );
    let o = compare(&whole, &whole, "1");
    assert!(o.status.success(), "{}", stderr(&o));
    // A missing part: an error naming the samples, no output.
    let lonely = dir.join("lonely.png");
    let o = merge(&lonely, &[&parts[0]]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("samples 2..4 of every pixel are in no part"),
        "{}",
        stderr(&o)
    );
    assert!(!lonely.exists());
    // A part as PNG, and a bad part flag, are refused before rendering.
    let o = run(&s(&with(&[
        "--part",
        "1/2",
        "-o",
        dir.join("p.png").to_str().unwrap(),
    ])));
    assert!(!o.status.success() && stderr(&o).contains("write it as .exr"));
    let o = run(&s(&with(&[
        "--part",
        "3/2",
        "-o",
        dir.join("p.exr").to_str().unwrap(),
    ])));
    assert!(!o.status.success() && stderr(&o).contains("--part wants I/N"));
    std::fs::remove_dir_all(&dir).ok();
}
