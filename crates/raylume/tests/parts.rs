//! Render parts (issue 16): parts that tile every pixel's samples merge into the render of all
//! of them, within `merge_bound` (the float-rounding bound derived in `src/parts.rs`), bit for
//! bit for one part of all the samples; on the CPU and on the GPU; bad part sets are refused.

mod common;

use raylume::{
    Backend, Part, SampleRange, Scene, Tracer, join, merge, merge_bound, worst_relative_difference,
};

/// Samples per pixel of the test renders.
const SPP: u32 = 6;

/// Renders part `i` of `n` with `tracer`.
fn part(tracer: &mut Tracer, scene: &Scene, i: u32, n: u32) -> Part {
    tracer.samples = Some(SampleRange::part(i, n, scene.render.spp).unwrap());
    let r = tracer.render(scene).unwrap();
    tracer.samples = None;
    assert!(r.stats.post_passes.is_empty(), "no bloom on a part");
    Part {
        header: r.part.expect("a part says it is one"),
        sums: r.pixels,
    }
}

fn parts_merge_into_the_render(backend: Backend) {
    let scene = common::small_cornell(SPP);
    for batch_spp in [2, 4] {
        let mut t = Tracer::new(backend);
        t.batch_spp = batch_spp;
        let whole = t.render(&scene).unwrap();
        assert!(whole.part.is_none());
        assert!(whole.pixels.iter().flatten().any(|v| *v > 0.0));
        // One part of all the samples: the same sums, the same division, bit for bit.
        let one = part(&mut t, &scene, 1, 1);
        let (_, merged) = merge(&[one], &[]).unwrap();
        assert_eq!(merged, whole.pixels, "{backend:?}, batches of {batch_spp}");
        for n in [2, 3, 6] {
            let parts: Vec<Part> = (1..=n).rev().map(|i| part(&mut t, &scene, i, n)).collect();
            let (header, merged) = merge(&parts, &[]).unwrap();
            assert_eq!(header.samples, SampleRange { begin: 0, end: 6 });
            let err = worst_relative_difference(&merged, &whole.pixels);
            assert!(
                err <= merge_bound(scene.render.spp),
                "{backend:?}, {n} parts, batches of {batch_spp}: relative error {err:.3e} past the bound {:.3e}",
                merge_bound(scene.render.spp)
            );
        }
        // The bound has teeth: another seed's render is far outside it.
        let mut other = Tracer::new(backend);
        other.seed = Some(scene.render.seed + 1);
        let o = other.render(&scene).unwrap();
        assert!(worst_relative_difference(&o.pixels, &whole.pixels) > 1e3 * merge_bound(6));
    }
}

#[test]
fn parts_merge_into_the_render_on_the_cpu() {
    parts_merge_into_the_render(Backend::Cpu);
}

#[test]
fn parts_merge_into_the_render_on_the_gpu() {
    if raylume_gpu::testing::context_or_skip("parts_merge_into_the_render_on_the_gpu").is_none() {
        return;
    }
    parts_merge_into_the_render(Backend::Gpu);
}

#[test]
fn bad_part_sets_are_refused() {
    let scene = common::small_cornell(SPP);
    let mut t = Tracer::new(Backend::Cpu);
    let p1 = part(&mut t, &scene, 1, 3);
    let p2 = part(&mut t, &scene, 2, 3);
    let p3 = part(&mut t, &scene, 3, 3);
    let names: Vec<String> = ["a.exr", "b.exr", "c.exr"].map(String::from).to_vec();
    let msg = |parts: &[Part]| merge(parts, &names).unwrap_err().to_string();
    assert!(msg(&[p1.clone(), p3.clone()]).contains("samples 2..4 of every pixel are in no part"));
    assert!(msg(&[p1.clone(), p2.clone()]).contains("samples 4..6 of every pixel are in no part"));
    assert!(msg(&[p2.clone(), p3.clone()]).contains("samples 0..2"));
    assert!(msg(&[p1.clone(), p1.clone(), p2.clone(), p3.clone()]).contains("overlaps"));
    assert!(msg(&[]).contains("no parts"));
    // Resuming: a part joined with the samples after it is one part of their union, and
    // merges like the parts it came from.
    let first_two = join(&[p2.clone(), p1.clone()], &names).unwrap();
    assert_eq!(first_two.header.samples, SampleRange { begin: 0, end: 4 });
    let (_, resumed) = merge(&[first_two, p3.clone()], &names).unwrap();
    let (_, direct) = merge(&[p1.clone(), p2.clone(), p3.clone()], &names).unwrap();
    assert!(
        resumed
            .iter()
            .zip(&direct)
            .all(|(a, b)| (0..3).all(|k| (a[k] - b[k]).abs() <= 1e-6 * b[k].abs()))
    );
    assert!(
        join(&[p1.clone(), p3.clone()], &names).is_err(),
        "a gap cannot be joined"
    );
    // A part of another render: another seed, another scene.
    let mut seeded = Tracer::new(Backend::Cpu);
    seeded.seed = Some(99);
    let other_seed = part(&mut seeded, &scene, 2, 3);
    let e = msg(&[p1.clone(), other_seed, p3.clone()]);
    assert!(
        e.contains("b.exr is of another render than a.exr: seed 99"),
        "{e}"
    );
    let mut moved = scene.clone();
    moved.camera.position.x += 0.01;
    let other_scene = part(&mut t, &moved, 3, 3);
    let e = msg(&[p1.clone(), p2.clone(), other_scene]);
    assert!(
        e.contains("c.exr is of another render than a.exr: scene"),
        "{e}"
    );
    // Ranges and settings a tracer refuses.
    assert!(SampleRange::part(0, 2, 6).is_err());
    assert!(SampleRange::part(3, 2, 6).is_err());
    assert!(
        SampleRange::part(1, 7, 6).is_err(),
        "7 parts of 6 samples: one would be empty"
    );
    t.samples = Some(SampleRange { begin: 4, end: 9 });
    assert!(t.render(&scene).is_err(), "past the render's samples");
    t.samples = Some(SampleRange { begin: 0, end: 2 });
    t.target_error = Some(1e-3);
    assert!(
        t.render(&scene).is_err(),
        "a part cannot stop at a target error"
    );
}

/// Equal parts tile `0..spp` for every count up to spp.
#[test]
fn equal_parts_tile_the_samples() {
    for spp in [1, 2, 7, 100, 1 << 20] {
        for n in [1, 2, 3, 7, 64].into_iter().filter(|&n| n <= spp) {
            let mut next = 0;
            for i in 1..=n {
                let r = SampleRange::part(i, n, spp).unwrap();
                assert_eq!(r.begin, next);
                assert!(
                    r.len() >= spp / n && r.len() <= spp / n + 1,
                    "{spp} {n} {i}: {r:?}"
                );
                next = r.end;
            }
            assert_eq!(next, spp);
        }
    }
}

/// A part survives its file bit for bit; files that are not parts are refused with a reason.
#[test]
fn parts_round_trip_through_exr() {
    let scene = common::small_cornell(SPP);
    let p = part(&mut Tracer::new(Backend::Cpu), &scene, 2, 3);
    let dir = std::env::temp_dir().join(format!("raylume-parts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("p2.exr");
    p.save(&file).unwrap();
    let back = Part::load(&file).unwrap();
    assert_eq!(back.header, p.header);
    assert_eq!(back.sums, p.sums);
    // A whole render's EXR has no part header.
    let whole = dir.join("whole.exr");
    Tracer::new(Backend::Cpu)
        .render(&scene)
        .unwrap()
        .save(&whole)
        .unwrap();
    let e = Part::load(&whole).unwrap_err().to_string();
    assert!(e.contains("not a raylume render part"), "{e}");
    let junk = dir.join("junk.exr");
    std::fs::write(&junk, b"not an image").unwrap();
    assert!(
        Part::load(&junk)
            .unwrap_err()
            .to_string()
            .contains("not a readable OpenEXR")
    );
    // A part is not written as PNG.
    let mut t = Tracer::new(Backend::Cpu);
    t.samples = Some(SampleRange::part(1, 2, 6).unwrap());
    let r = t.render(&scene).unwrap();
    assert!(r.save(dir.join("p.png")).is_err());
    assert!(!dir.join("p.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}
