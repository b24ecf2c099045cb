//! Tessellates Martin Newell's Utah teapot (32 bicubic Bézier patches, `.bpt` text form) into
//! a binary glTF mesh: `scenes/teapot/teapot.glb`, used by `scenes/teapot.toml` and
//! `scenes/glass-teapot.toml` (the paper's "Teapot" and "Glass teapot").
//!
//! ```text
//! cargo run --release --example make_teapot -- scenes/teapot/teapot.bpt scenes/teapot/teapot.glb [--grid N]
//! ```
//!
//! Each patch is evaluated on a uniform `(N+1) x (N+1)` grid of `(u, v)` (default `N = 44`:
//! `32 * 44 * 44 * 2 = 123,904` triangles before dropping degenerate ones, the closest to the
//! paper's 126,050). Normals are analytic, `S_u x S_v` from the Bézier partial derivatives; where
//! that cross product vanishes (the lid's knob and the bottom's centre, where a whole patch
//! edge collapses to a point) the normal is taken a tiny step inside the patch instead.
//!
//! Triangles with two coincident corners (exactly one per grid quad along a collapsed patch
//! edge: `8 * N` of them for the 8 patches that have one) are **dropped here**, so the file
//! holds `32 * 2 * N^2 - 8 * N` triangles (123,552 at `N = 44`).
//!
//! Vertices on patch edges are shared between neighbouring patches where both position and
//! normal agree (not across creases), 62,130 of the `32 * 45 * 45 = 64,800` grid points
//! at `N = 44`; this keeps the file at ~2.2 MB.
//!
//! The `.bpt` data is z-up; the output is y-up (`(x, y, z) -> (x, z, -y)`, a proper rotation
//! of -90 degrees about x). Each patch's triangles are wound counter-clockwise about its
//! outward normal (glTF's front face). The output holds POSITION, NORMAL and u16 indices
//! (u32 when more than 65,535 vertices), one mesh, one node, no material. It is
//! byte-for-byte deterministic.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::process::ExitCode;

use glam::DVec3;
use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;

/// One bicubic patch: `points[i][j]`, `i` along `u` (the `.bpt` rows), `j` along `v`.
type Patch = [[DVec3; 4]; 4];

/// Default quads per patch edge.
const DEFAULT_GRID: usize = 44;

/// Parameter step used to find the normal where `S_u x S_v` vanishes.
const INSIDE_STEP: f64 = 1e-4;

/// Patch-edge vertices whose positions agree after rounding to `1 / WELD_SCALE` (the surface
/// is ~6 units across; adjacent patches evaluate their shared edge to within ~1e-15) and
/// whose normals agree within `acos(WELD_MIN_COS)` (~0.8 degrees) are shared between the
/// patches. Across a crease (normals disagree) each patch keeps its own vertex.
const WELD_SCALE: f64 = 1e6;
const WELD_MIN_COS: f64 = 0.9999;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("make_teapot: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let usage = "usage: make_teapot <input.bpt> <output.glb> [--grid N]";
    let mut positional = Vec::new();
    let mut grid = DEFAULT_GRID;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        if arg == "--grid" {
            let value = args
                .next()
                .ok_or(format!("--grid needs a value\n{usage}"))?;
            grid = value
                .parse()
                .ok()
                .filter(|&n: &usize| n >= 1)
                .ok_or(format!("--grid: '{value}' is not a positive integer"))?;
        } else if arg.starts_with("--") {
            return Err(format!("unknown flag '{arg}'\n{usage}"));
        } else {
            positional.push(arg);
        }
    }
    let [input, output] = positional.as_slice() else {
        return Err(usage.to_string());
    };

    let text = std::fs::read_to_string(input).map_err(|e| format!("{input}: {e}"))?;
    let patches = parse_bpt(&text).map_err(|e| format!("{input}: {e}"))?;
    let mesh = tessellate(&patches, grid);
    let glb = to_glb(&mesh)?;
    std::fs::write(output, &glb).map_err(|e| format!("{output}: {e}"))?;

    let full = patches.len() * grid * grid * 2;
    println!(
        "{} patches, grid {grid}: {} vertices, {} triangles ({full} minus {} degenerate), \
         {} bytes -> {output}",
        patches.len(),
        mesh.positions.len(),
        mesh.indices.len() / 3,
        mesh.degenerate,
        glb.len()
    );
    println!("bounds min {:?} max {:?}", mesh.min, mesh.max);
    println!(
        "{} of {} patches had S_u x S_v pointing inward and were turned round",
        mesh.flipped.len(),
        patches.len()
    );
    Ok(())
}

/// Parses the `.bpt` text form: a patch count, then per patch a line `3 3` and 16 lines
/// `x y z`, row by row.
fn parse_bpt(text: &str) -> Result<Vec<Patch>, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    let mut next = |what: &str| {
        lines
            .next()
            .ok_or(format!("unexpected end of file, expected {what}"))
    };

    let (line, count) = next("the patch count")?;
    let count: usize = count
        .parse()
        .map_err(|_| format!("line {line}: '{count}' is not a patch count"))?;
    let mut patches = Vec::with_capacity(count);
    for p in 0..count {
        let (line, degrees) = next("a patch header '3 3'")?;
        if degrees.split_whitespace().collect::<Vec<_>>() != ["3", "3"] {
            return Err(format!(
                "line {line}: patch {p} has degrees '{degrees}', only bicubic '3 3' is supported"
            ));
        }
        let mut patch = [[DVec3::ZERO; 4]; 4];
        for k in 0..16 {
            let (line, point) = next("a control point")?;
            let xyz: Vec<f64> = point
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| format!("line {line}: '{point}' is not 'x y z'"))?;
            let [x, y, z] = xyz[..] else {
                return Err(format!("line {line}: '{point}' is not 'x y z'"));
            };
            patch[k / 4][k % 4] = DVec3::new(x, y, z);
        }
        patches.push(patch);
    }
    if let Some((line, extra)) = lines.next() {
        return Err(format!(
            "line {line}: unexpected '{extra}' after {count} patches"
        ));
    }
    Ok(patches)
}

/// Cubic Bernstein basis and its derivative at `t`.
fn bernstein(t: f64) -> ([f64; 4], [f64; 4]) {
    let s = 1.0 - t;
    let b = [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t];
    let d = [
        -3.0 * s * s,
        3.0 * s * s - 6.0 * t * s,
        6.0 * t * s - 3.0 * t * t,
        3.0 * t * t,
    ];
    (b, d)
}

/// Point and partial derivatives `(S, S_u, S_v)` of a patch at `(u, v)`.
fn evaluate(patch: &Patch, u: f64, v: f64) -> (DVec3, DVec3, DVec3) {
    let (bu, du) = bernstein(u);
    let (bv, dv) = bernstein(v);
    let (mut s, mut su, mut sv) = (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
    for i in 0..4 {
        for j in 0..4 {
            let p = patch[i][j];
            s += bu[i] * bv[j] * p;
            su += du[i] * bv[j] * p;
            sv += bu[i] * dv[j] * p;
        }
    }
    (s, su, sv)
}

/// The unnormalised normal `S_u x S_v`, taken a tiny step toward the patch centre where it
/// vanishes (a collapsed edge: one partial derivative is zero there).
fn patch_normal(patch: &Patch, u: f64, v: f64) -> DVec3 {
    let (_, su, sv) = evaluate(patch, u, v);
    let n = su.cross(sv);
    if n.length() > 1e-9 * (su.length_squared() + sv.length_squared()).max(1e-300) {
        return n;
    }
    let inward = |t: f64| t + INSIDE_STEP * (0.5 - t).signum();
    let (_, su, sv) = evaluate(patch, inward(u), inward(v));
    su.cross(sv)
}

/// z-up (the `.bpt` data) to y-up: a rotation of -90 degrees about +x.
fn z_up_to_y_up(p: DVec3) -> DVec3 {
    DVec3::new(p.x, p.z, -p.y)
}

/// `+1` where a patch's `S_u x S_v` points out of the teapot, `-1` where it points in.
///
/// The teapot is no closed surface (spout and handle pierce the body without a hole), so the
/// side is judged from its shape at the patch centre `s` with normal `n`:
/// - spout and handle are tubes lying in the plane y = 0 (the only patches reaching beyond the
///   body's largest radius, 2.0): at a patch centre, half-way round the tube, outward is `+-y`
///   with the sign of `s.y`;
/// - the rest (rim, body, lid, knob, bottom) are surfaces of revolution about z: where the
///   normal is mostly vertical (lid, knob top, lip top, bottom) outward is up above the body's
///   middle height and down below it; elsewhere outward is away from the axis.
fn outward_sign(patch: &Patch) -> f64 {
    let (s, _, _) = evaluate(patch, 0.5, 0.5);
    let n = patch_normal(patch, 0.5, 0.5).normalize();
    let reach = patch
        .iter()
        .flatten()
        .map(|p| p.truncate().length())
        .fold(0.0, f64::max);
    let radial = DVec3::new(s.x, s.y, 0.0).normalize_or_zero();
    let away = if reach > 2.05 {
        DVec3::new(0.0, s.y.signum(), 0.0)
    } else if n.z.abs() > n.dot(radial).abs() {
        DVec3::new(0.0, 0.0, if s.z > 1.5 { 1.0 } else { -1.0 })
    } else {
        radial
    };
    if n.dot(away) >= 0.0 { 1.0 } else { -1.0 }
}

struct TriMesh {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    indices: Vec<u32>,
    degenerate: usize,
    /// Patches whose `S_u x S_v` pointed inward (normals and winding reversed).
    flipped: Vec<usize>,
    min: [f32; 3],
    max: [f32; 3],
}

fn tessellate(patches: &[Patch], grid: usize) -> TriMesh {
    let side = grid + 1;
    let mut mesh = TriMesh {
        positions: Vec::with_capacity(patches.len() * side * side),
        normals: Vec::with_capacity(patches.len() * side * side),
        indices: Vec::with_capacity(patches.len() * grid * grid * 6),
        degenerate: 0,
        flipped: Vec::new(),
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };
    // Patch-edge vertices already emitted, by quantised position (a BTreeMap keeps the output
    // deterministic), and the exact normals of all vertices.
    let mut welds: BTreeMap<[i64; 3], Vec<u32>> = BTreeMap::new();
    let mut normals64: Vec<DVec3> = Vec::new();
    for (index, patch) in patches.iter().enumerate() {
        let sign = outward_sign(patch);
        if sign < 0.0 {
            mesh.flipped.push(index);
        }
        // Global vertex index of each grid point of this patch.
        let mut local = Vec::with_capacity(side * side);
        for i in 0..side {
            let u = i as f64 / grid as f64;
            for j in 0..side {
                let v = j as f64 / grid as f64;
                let (s, _, _) = evaluate(patch, u, v);
                let n = z_up_to_y_up(sign * patch_normal(patch, u, v).normalize());
                let s = z_up_to_y_up(s);
                let on_edge = i == 0 || j == 0 || i == grid || j == grid;
                let key = (s * WELD_SCALE).round().as_i64vec3().to_array();
                let shared = welds.get(&key).filter(|_| on_edge).and_then(|candidates| {
                    candidates
                        .iter()
                        .find(|&&k| n.dot(normals64[k as usize]) >= WELD_MIN_COS)
                });
                if let Some(&k) = shared {
                    local.push(k);
                    continue;
                }
                let k = mesh.positions.len() as u32;
                if on_edge {
                    welds.entry(key).or_default().push(k);
                }
                let p = s.as_vec3();
                mesh.min = p.min(mesh.min.into()).to_array();
                mesh.max = p.max(mesh.max.into()).to_array();
                mesh.positions.push(p.to_array());
                mesh.normals.push(n.as_vec3().to_array());
                normals64.push(n);
                local.push(k);
            }
        }
        let at = |i: usize, j: usize| local[i * side + j];
        for i in 0..grid {
            for j in 0..grid {
                // Counter-clockwise in (u, v), so about S_u x S_v; reversed for patches whose
                // S_u x S_v points inward.
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                for tri in [[a, b, c], [a, c, d]] {
                    let [p0, p1, p2] = tri.map(|k| mesh.positions[k as usize]);
                    if p0 == p1 || p1 == p2 || p2 == p0 {
                        mesh.degenerate += 1;
                        continue;
                    }
                    if sign > 0.0 {
                        mesh.indices.extend(tri);
                    } else {
                        mesh.indices.extend([tri[0], tri[2], tri[1]]);
                    }
                }
            }
        }
    }
    mesh
}

/// Appends `bytes` to `bin` (4-byte aligned) and returns its buffer view.
fn push_view(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    bytes: &[u8],
    target: json::buffer::Target,
) -> json::Index<json::buffer::View> {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend_from_slice(bytes);
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(bytes.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        target: Some(Valid(target)),
    })
}

fn accessor(
    view: json::Index<json::buffer::View>,
    count: usize,
    component: json::accessor::ComponentType,
    type_: json::accessor::Type,
    bounds: Option<([f32; 3], [f32; 3])>,
) -> json::Accessor {
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(component)),
        extensions: Default::default(),
        extras: Default::default(),
        type_: Valid(type_),
        min: bounds.map(|(min, _)| json::Value::from(min.to_vec())),
        max: bounds.map(|(_, max)| json::Value::from(max.to_vec())),
        name: None,
        normalized: false,
        sparse: None,
    }
}

fn to_glb(mesh: &TriMesh) -> Result<Vec<u8>, String> {
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;

    let le_f32 =
        |v: &[[f32; 3]]| -> Vec<u8> { v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect() };
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some("raylume examples/make_teapot.rs".into()),
            copyright: Some("Utah teapot: Martin Newell, 1975, public domain".into()),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut bin = Vec::new();

    let positions = push_view(
        &mut root,
        &mut bin,
        &le_f32(&mesh.positions),
        Target::ArrayBuffer,
    );
    let normals = push_view(
        &mut root,
        &mut bin,
        &le_f32(&mesh.normals),
        Target::ArrayBuffer,
    );
    let (index_bytes, index_type): (Vec<u8>, _) = if mesh.positions.len() <= u16::MAX as usize {
        let bytes = mesh
            .indices
            .iter()
            .flat_map(|&i| (i as u16).to_le_bytes())
            .collect();
        (bytes, ComponentType::U16)
    } else {
        let bytes = mesh.indices.iter().flat_map(|&i| i.to_le_bytes()).collect();
        (bytes, ComponentType::U32)
    };
    let indices = push_view(
        &mut root,
        &mut bin,
        &index_bytes,
        Target::ElementArrayBuffer,
    );
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }

    let n = mesh.positions.len();
    let positions = root.push(accessor(
        positions,
        n,
        ComponentType::F32,
        Type::Vec3,
        Some((mesh.min, mesh.max)),
    ));
    let normals = root.push(accessor(normals, n, ComponentType::F32, Type::Vec3, None));
    let indices = root.push(accessor(
        indices,
        mesh.indices.len(),
        index_type,
        Type::Scalar,
        None,
    ));
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        uri: None,
    });

    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
    attributes.insert(Valid(json::mesh::Semantic::Normals), normals);
    let mesh_index = root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some("teapot".into()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(indices),
            material: None,
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some("teapot".into()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);

    let json = json::serialize::to_vec(&root).map_err(|e| format!("glTF JSON: {e}"))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // computed by to_vec
        },
        json: Cow::Owned(json),
        bin: Some(Cow::Owned(bin)),
    };
    glb.to_vec().map_err(|e| format!("glTF binary: {e}"))
}
