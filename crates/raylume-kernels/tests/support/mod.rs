//! Fixture scenes built in code, and helpers the tests share.
#![allow(dead_code)]

use glam::{Vec2, Vec3};
use raylume_bvh::{BvhQuality, GpuBvh};
use raylume_kernels::{CpuTracer, GpuTracer, Schedule, TraceOutput, TraceSettings};
use raylume_scene::{Camera, Environment, FovAxis, Material, Scene, Sphere, Texture, Triangle};

/// Two triangles: corner, corner + u, corner + u + v, corner + v, with uvs (0,0)..(1,1).
pub fn quad(corner: Vec3, u: Vec3, v: Vec3, material: u32) -> [Triangle; 2] {
    let (p0, p1, p2, p3) = (corner, corner + u, corner + u + v, corner + v);
    let (t0, t1, t2, t3) = (Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y);
    [
        Triangle {
            positions: [p0, p1, p2],
            normals: None,
            uvs: Some([t0, t1, t2]),
            material,
        },
        Triangle {
            positions: [p0, p2, p3],
            normals: None,
            uvs: Some([t0, t2, t3]),
            material,
        },
    ]
}

/// Quad without uvs.
pub fn flat_quad(corner: Vec3, u: Vec3, v: Vec3, material: u32) -> [Triangle; 2] {
    quad(corner, u, v, material).map(|mut t| {
        t.uvs = None;
        t
    })
}

/// A box of `size` centred at `center`, turned by `yaw` degrees about +y: 12 triangles.
pub fn cuboid(center: Vec3, size: Vec3, yaw: f32, material: u32) -> Vec<Triangle> {
    let r = glam::Quat::from_rotation_y(yaw.to_radians());
    let h = size * 0.5;
    let corner = |s: Vec3| center + r * (h * s);
    let faces = [
        (Vec3::new(-1., -1., 1.), Vec3::X, Vec3::Y),  // front
        (Vec3::new(1., -1., -1.), -Vec3::X, Vec3::Y), // back
        (Vec3::new(-1., -1., -1.), Vec3::Z, Vec3::Y), // left
        (Vec3::new(1., -1., 1.), -Vec3::Z, Vec3::Y),  // right
        (Vec3::new(-1., 1., 1.), Vec3::X, -Vec3::Z),  // top
        (Vec3::new(-1., -1., -1.), Vec3::X, Vec3::Z), // bottom
    ];
    let mut out = Vec::new();
    for (c, u, v) in faces {
        let p = corner(c);
        out.extend(flat_quad(
            p,
            corner(c + 2.0 * u) - p,
            corner(c + 2.0 * v) - p,
            material,
        ));
    }
    out
}

/// The Cornell box in [-1, 1] x [0, 2] x [-1, 1] with a ceiling light and two boxes.
pub fn cornell_box() -> Scene {
    let materials = vec![
        Material::diffuse("white", Vec3::splat(0.73)),
        Material::diffuse("red", Vec3::new(0.65, 0.05, 0.05)),
        Material::diffuse("green", Vec3::new(0.12, 0.45, 0.15)),
        Material::emissive("light", Vec3::new(17.0, 12.0, 4.0)),
    ];
    let mut t = Vec::new();
    t.extend(flat_quad(
        Vec3::new(-1., 0., -1.),
        Vec3::new(2., 0., 0.),
        Vec3::new(0., 0., 2.),
        0,
    )); // floor
    t.extend(flat_quad(
        Vec3::new(-1., 2., -1.),
        Vec3::new(2., 0., 0.),
        Vec3::new(0., 0., 2.),
        0,
    )); // ceiling
    t.extend(flat_quad(
        Vec3::new(-1., 0., -1.),
        Vec3::new(2., 0., 0.),
        Vec3::new(0., 2., 0.),
        0,
    )); // back
    t.extend(flat_quad(
        Vec3::new(-1., 0., -1.),
        Vec3::new(0., 0., 2.),
        Vec3::new(0., 2., 0.),
        1,
    )); // left
    t.extend(flat_quad(
        Vec3::new(1., 0., -1.),
        Vec3::new(0., 0., 2.),
        Vec3::new(0., 2., 0.),
        2,
    )); // right
    t.extend(flat_quad(
        Vec3::new(-0.25, 1.98, -0.25),
        Vec3::new(0.5, 0., 0.),
        Vec3::new(0., 0., 0.5),
        3,
    ));
    t.extend(cuboid(
        Vec3::new(0.33, 0.3, 0.3),
        Vec3::splat(0.6),
        -17.0,
        0,
    ));
    t.extend(cuboid(
        Vec3::new(-0.33, 0.6, -0.3),
        Vec3::new(0.6, 1.2, 0.6),
        17.0,
        0,
    ));
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 1.0, 6.8),
            look_at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov: 19.5,
            fov_axis: FovAxis::Vertical,
        },
        materials,
        triangles: t,
        ..Default::default()
    }
}

/// Metal (mirror and rough), glass (clear and tinted), diffuse and emissive spheres on a
/// diffuse floor under a constant sky.
pub fn spheres() -> Scene {
    let materials = vec![
        Material::diffuse("floor", Vec3::new(0.6, 0.6, 0.5)),
        Material::metal("mirror", Vec3::new(0.95, 0.9, 0.8), 0.0),
        Material::metal("brushed", Vec3::new(0.9, 0.6, 0.3), 0.4),
        Material::glass("glass", 1.5, Vec3::ONE),
        Material::glass("tinted", 1.33, Vec3::new(0.6, 0.9, 1.0)),
        Material::diffuse("blue", Vec3::new(0.2, 0.3, 0.8)),
        Material::emissive("lamp", Vec3::new(8.0, 6.0, 3.0)),
    ];
    let s = |x: f32, y: f32, z: f32, r: f32, m: u32| Sphere {
        center: Vec3::new(x, y, z),
        radius: r,
        material: m,
    };
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 1.2, 4.0),
            look_at: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            fov: 45.0,
            fov_axis: FovAxis::Vertical,
        },
        materials,
        triangles: flat_quad(
            Vec3::new(-4., 0., -4.),
            Vec3::new(0., 0., 8.),
            Vec3::new(8., 0., 0.),
            0,
        )
        .to_vec(),
        spheres: vec![
            s(-1.6, 0.5, 0.0, 0.5, 1),
            s(-0.55, 0.5, -0.3, 0.5, 2),
            s(0.55, 0.5, 0.2, 0.5, 3),
            s(1.6, 0.5, -0.2, 0.5, 4),
            s(0.0, 0.25, 1.1, 0.25, 5),
            s(0.3, 1.6, -1.0, 0.3, 6),
        ],
        environment: Environment::Constant(Vec3::new(0.5, 0.6, 0.8)),
        ..Default::default()
    }
}

/// Every material the Bitterli scenes use, on spheres over a textured rough-plastic floor,
/// under a constant sky and a one-sided lamp: smooth and rough plastic (two roughnesses, so two
/// coat tables), smooth and rough conductors with complex IORs (gold, aluminium) and a
/// Fresnel-1 mirror, rough glass.
pub fn materials() -> Scene {
    let au = raylume_scene::conductor_ior("Au").unwrap();
    let al = raylume_scene::conductor_ior("Al").unwrap();
    let mut floor = Material::plastic("floor", Vec3::new(0.7, 0.6, 0.5), 1.5, 0.4);
    floor.albedo_texture = Some(0);
    let materials = vec![
        floor,
        Material::plastic("smooth plastic", Vec3::new(0.2, 0.3, 0.8), 1.5, 0.0),
        Material::plastic("rough plastic", Vec3::new(0.8, 0.2, 0.1), 1.4, 0.2),
        Material::conductor("gold", au.0, au.1, Vec3::ONE, 0.3),
        Material::conductor("aluminium", al.0, al.1, Vec3::splat(0.6), 0.0),
        Material::metal("mirror", Vec3::splat(0.9), 0.0),
        Material {
            roughness: 0.3,
            ..Material::glass("frosted", 1.5, Vec3::new(0.9, 1.0, 0.9))
        },
        Material::emissive("lamp", Vec3::new(8.0, 6.0, 3.0)),
    ];
    let s = |x: f32, y: f32, z: f32, r: f32, m: u32| Sphere {
        center: Vec3::new(x, y, z),
        radius: r,
        material: m,
    };
    let mut triangles = quad(
        Vec3::new(-4., 0., -4.),
        Vec3::new(0., 0., 8.),
        Vec3::new(8., 0., 0.),
        0,
    )
    .to_vec();
    // A lamp above, facing down (u x v = -y).
    triangles.extend(flat_quad(
        Vec3::new(-0.5, 2.5, -0.5),
        Vec3::new(1., 0., 0.),
        Vec3::new(0., 0., 1.),
        7,
    ));
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 1.2, 4.0),
            look_at: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            fov: 50.0,
            fov_axis: FovAxis::Vertical,
        },
        materials,
        textures: vec![test_texture(8, 8)],
        triangles,
        spheres: vec![
            s(-1.8, 0.4, 0.0, 0.4, 1),
            s(-0.9, 0.4, -0.3, 0.4, 2),
            s(0.0, 0.4, 0.2, 0.4, 3),
            s(0.9, 0.4, -0.2, 0.4, 4),
            s(1.8, 0.4, 0.0, 0.4, 5),
            s(0.0, 0.3, 1.2, 0.3, 6),
        ],
        environment: Environment::Constant(Vec3::new(0.5, 0.6, 0.8)),
        ..Default::default()
    }
}

/// An RGB checkerboard-ish texture whose texels all differ (so a wrong texel shows).
pub fn test_texture(w: u32, h: u32) -> Texture {
    let texels = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let c = if (x + y) % 2 == 0 { 0.9 } else { 0.2 };
                [c, (x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32]
            })
        })
        .collect();
    Texture {
        name: "test".into(),
        width: w,
        height: h,
        texels,
    }
}

/// A textured floor (uvs spanning 3x3 repeats), a textured sphere, and a bumpy triangle fan
/// with shading normals, under a constant sky.
pub fn textured() -> Scene {
    let mut floor = quad(
        Vec3::new(-2., 0., -2.),
        Vec3::new(0., 0., 4.),
        Vec3::new(4., 0., 0.),
        0,
    );
    for t in &mut floor {
        t.uvs = t.uvs.map(|uv| uv.map(|p| p * 3.0 - Vec2::splat(0.5)));
    }
    let mut tris = floor.to_vec();
    // A fan of triangles forming a low pyramid, with smooth (averaged) normals.
    let apex = Vec3::new(0.6, 0.7, 0.0);
    let ring: Vec<Vec3> = (0..6)
        .map(|i| {
            let a = i as f32 * std::f32::consts::TAU / 6.0;
            Vec3::new(0.6 + 0.6 * a.cos(), 0.05, 0.6 * a.sin())
        })
        .collect();
    for i in 0..6 {
        let (a, b) = (ring[i], ring[(i + 1) % 6]);
        let n = |p: Vec3| (p - Vec3::new(0.6, -0.3, 0.0)).normalize();
        tris.push(Triangle {
            positions: [apex, a, b],
            normals: Some([Vec3::Y, n(a), n(b)]),
            uvs: None,
            material: 2,
        });
    }
    let mut tex_material = Material::diffuse("checker", Vec3::ONE);
    tex_material.albedo_texture = Some(0);
    let mut sphere_material = Material::metal("textured metal", Vec3::splat(0.9), 0.2);
    sphere_material.albedo_texture = Some(1);
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 2.0, 3.0),
            look_at: Vec3::new(0.0, 0.2, 0.0),
            up: Vec3::Y,
            fov: 50.0,
            fov_axis: FovAxis::Vertical,
        },
        materials: vec![
            tex_material,
            sphere_material,
            Material::diffuse("bump", Vec3::new(0.8, 0.7, 0.6)),
        ],
        textures: vec![test_texture(8, 8), test_texture(5, 3)],
        triangles: tris,
        spheres: vec![Sphere {
            center: Vec3::new(-0.8, 0.5, 0.0),
            radius: 0.5,
            material: 1,
        }],
        environment: Environment::Constant(Vec3::new(1.0, 0.9, 0.8)),
        ..Default::default()
    }
}

/// A procedural sky map: a vertical gradient with a bright sun, varying along longitude.
pub fn sky_map(w: u32, h: u32) -> Texture {
    let texels = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let v = (y as f32 + 0.5) / h as f32;
                let u = (x as f32 + 0.5) / w as f32;
                let sun = if (u - 0.3).abs() < 0.05 && (v - 0.3).abs() < 0.08 {
                    20.0
                } else {
                    0.0
                };
                [
                    0.2 + (1.0 - v) + sun,
                    0.3 + u * 0.5 + sun,
                    1.0 - 0.5 * v + sun * 0.8,
                ]
            })
        })
        .collect();
    Texture {
        name: "sky".into(),
        width: w,
        height: h,
        texels,
    }
}

/// Diffuse, mirror and glass spheres under an equirectangular sky map (rotated 30 degrees).
pub fn environment_lit() -> Scene {
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 0.6, 4.0),
            look_at: Vec3::new(0.0, 0.4, 0.0),
            up: Vec3::Y,
            fov: 60.0,
            fov_axis: FovAxis::Vertical,
        },
        materials: vec![
            Material::diffuse("white", Vec3::splat(0.8)),
            Material::metal("mirror", Vec3::splat(0.9), 0.0),
            Material::glass("glass", 1.5, Vec3::ONE),
        ],
        spheres: vec![
            Sphere {
                center: Vec3::new(-1.1, 0.5, 0.0),
                radius: 0.5,
                material: 0,
            },
            Sphere {
                center: Vec3::new(0.0, 0.5, 0.0),
                radius: 0.5,
                material: 1,
            },
            Sphere {
                center: Vec3::new(1.1, 0.5, 0.0),
                radius: 0.5,
                material: 2,
            },
        ],
        triangles: flat_quad(
            Vec3::new(-3., 0., -3.),
            Vec3::new(0., 0., 6.),
            Vec3::new(6., 0., 0.),
            0,
        )
        .to_vec(),
        environment: Environment::Map {
            image: sky_map(32, 16),
            strength: 1.5,
            rotation: 30.0,
        },
        ..Default::default()
    }
}

/// The four fixtures the schedule tests render (diffuse with an area light; spheres of metal
/// and glass; textures; an environment), named.
/// The wavefront's rays sorted (by index) before every bounce from `depth` on.
pub fn sorted_from(depth: u32) -> raylume_kernels::Reorder {
    raylume_kernels::Reorder::from_depth(raylume_kernels::ReorderMode::SortIndex, depth)
}

pub fn schedule_scenes() -> [(&'static str, Scene); 4] {
    [
        ("cornell", cornell_box()),
        ("spheres", spheres()),
        ("textured", textured()),
        ("environment", environment_lit()),
    ]
}

pub fn bvh(scene: &Scene) -> GpuBvh {
    GpuBvh::from_scene(scene, BvhQuality::Fast).expect("fixture BVH builds")
}

pub fn bvh_with_layout(scene: &Scene, layout: raylume_bvh::BvhLayout) -> GpuBvh {
    GpuBvh::from_scene_with_layout(scene, BvhQuality::Fast, layout).expect("fixture BVH builds")
}

pub fn settings(w: u32, h: u32, spp: u32, max_bounces: u32, schedule: Schedule) -> TraceSettings {
    TraceSettings {
        width: w,
        height: h,
        spp,
        max_bounces,
        seed: 7,
        batch_spp: 20,
        schedule,
        reorder: raylume_kernels::Reorder::OFF,
    }
}

pub fn render_cpu(scene: &Scene, s: &TraceSettings) -> TraceOutput {
    CpuTracer::new(scene, &bvh(scene))
        .expect("CPU tracer")
        .render(s, &mut |_, _| {})
        .expect("CPU render")
}

pub fn render_gpu(ctx: &raylume_gpu::GpuContext, scene: &Scene, s: &TraceSettings) -> TraceOutput {
    GpuTracer::new(ctx, scene, &bvh(scene))
        .expect("GPU tracer")
        .render(s, &mut |_, _| {})
        .expect("GPU render")
}

/// Relative RMSE of `a` against `b` over all channels: sqrt(mean((a-b)^2) / mean(b^2)).
pub fn relative_rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    assert_eq!(a.len(), b.len());
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        for c in 0..3 {
            let d = f64::from(x[c]) - f64::from(y[c]);
            num += d * d;
            den += f64::from(y[c]) * f64::from(y[c]);
        }
    }
    (num / den.max(1e-30)).sqrt()
}

/// Mean of each channel.
pub fn mean(img: &[[f32; 3]]) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for p in img {
        for c in 0..3 {
            m[c] += f64::from(p[c]);
        }
    }
    m.map(|x| x / img.len() as f64)
}

/// A closed room [-1, 1] x [0, 2] x [-1, 1] of grey diffuse walls lit only by a constant sky
/// through a square skylight `opening` wide in the middle of its ceiling (none: a closed box),
/// the camera inside looking at the far wall and the floor.
pub fn skylight_room(opening: f32) -> Scene {
    let m = 0;
    let mut triangles = Vec::new();
    // Floor, four walls (normals inward does not matter: the shading flips them).
    triangles.extend(flat_quad(
        Vec3::new(-1., 0., -1.),
        Vec3::new(0., 0., 2.),
        Vec3::new(2., 0., 0.),
        m,
    ));
    triangles.extend(flat_quad(
        Vec3::new(-1., 0., -1.),
        Vec3::new(2., 0., 0.),
        Vec3::new(0., 2., 0.),
        m,
    ));
    triangles.extend(flat_quad(
        Vec3::new(-1., 0., 1.),
        Vec3::new(0., 2., 0.),
        Vec3::new(2., 0., 0.),
        m,
    ));
    triangles.extend(flat_quad(
        Vec3::new(-1., 0., -1.),
        Vec3::new(0., 2., 0.),
        Vec3::new(0., 0., 2.),
        m,
    ));
    triangles.extend(flat_quad(
        Vec3::new(1., 0., -1.),
        Vec3::new(0., 0., 2.),
        Vec3::new(0., 2., 0.),
        m,
    ));
    // The ceiling at y = 2 around the opening [-h, h]^2 (x, z).
    let h = opening * 0.5;
    let y = 2.0;
    let mut ceiling = |x0: f32, x1: f32, z0: f32, z1: f32| {
        if x1 > x0 && z1 > z0 {
            triangles.extend(flat_quad(
                Vec3::new(x0, y, z0),
                Vec3::new(x1 - x0, 0., 0.),
                Vec3::new(0., 0., z1 - z0),
                m,
            ));
        }
    };
    ceiling(-1.0, -h, -1.0, 1.0);
    ceiling(h, 1.0, -1.0, 1.0);
    ceiling(-h, h, -1.0, -h);
    ceiling(-h, h, h, 1.0);
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 1.0, 0.9),
            look_at: Vec3::new(0.0, 0.6, -1.0),
            up: Vec3::Y,
            fov: 70.0,
            fov_axis: FovAxis::Vertical,
        },
        materials: vec![Material::diffuse("walls", Vec3::splat(0.6))],
        triangles,
        environment: Environment::Constant(Vec3::new(1.0, 0.9, 0.8)),
        ..Default::default()
    }
}
