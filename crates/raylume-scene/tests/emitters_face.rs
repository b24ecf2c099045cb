//! Emission is one-sided (from the front face, the side the geometric normal points to), so
//! a lamp wound the wrong way lights nothing. Every emitter of every scene shipped in
//! `scenes/` must face the room: its front normal points towards the camera's side of the lamp
//! and towards the centre of the scene's bounds.

use std::path::Path;

use raylume_scene::Scene;

#[test]
fn every_shipped_lamp_faces_the_room() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut lamps = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let path = if path.is_dir() {
            path.join("scene.json")
        } else {
            path
        };
        if !matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("toml" | "json")
        ) || !path.exists()
        {
            continue;
        }
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let b = scene.bounds();
        let center = (b.min + b.max) * 0.5;
        for (i, t) in scene.triangles.iter().enumerate() {
            let m = &scene.materials[t.material as usize];
            if !m.is_emissive() || m.two_sided {
                continue;
            }
            let [a, p1, p2] = t.positions;
            let n = (p1 - a).cross(p2 - a);
            let centroid = (a + p1 + p2) / 3.0;
            let to_center = n.dot(center - centroid);
            let to_camera = n.dot(scene.camera.position - centroid);
            assert!(
                to_center > 0.0 && to_camera > 0.0,
                "{}: emissive triangle {i} (`{}`) faces away from the room (normal {}, \
                 centre {center}, camera {})",
                path.display(),
                m.name,
                n.normalize(),
                scene.camera.position
            );
            lamps += 1;
        }
        for s in &scene.spheres {
            // A sphere emits outwards: the camera must be outside an emitting sphere.
            if scene.materials[s.material as usize].is_emissive() {
                assert!(scene.camera.position.distance(s.center) > s.radius);
                lamps += 1;
            }
        }
    }
    // The three Cornell boxes' ceiling lamps (2 triangles each).
    assert!(lamps >= 6, "{lamps} emitters found");
}
