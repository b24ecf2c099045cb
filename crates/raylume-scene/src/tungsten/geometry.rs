//! Tungsten's transforms and its quad and cube primitives, in double precision.

use glam::{DMat3, DMat4, DVec3, Vec3};

use super::json::J;
use crate::error::SceneError;
use crate::transform::sin_cos_deg;

/// Tungsten's `Mat4f::rotYXZ`, copied term by term (degrees), in double precision with exact
/// right angles.
pub(crate) fn rot_yxz(rot: DVec3) -> DMat3 {
    let (sx, cx) = sin_cos_deg(rot.x);
    let (sy, cy) = sin_cos_deg(rot.y);
    let (sz, cz) = sin_cos_deg(rot.z);
    let (c, s) = ([cx, cy, cz], [sx, sy, sz]);
    // Rows as written in Tungsten; glam takes columns, hence the transpose.
    DMat3::from_cols(
        DVec3::new(
            c[1] * c[2] - s[1] * s[0] * s[2],
            -c[1] * s[2] - s[1] * s[0] * c[2],
            -s[1] * c[0],
        ),
        DVec3::new(c[0] * s[2], c[0] * c[2], -s[0]),
        DVec3::new(
            s[1] * c[2] + c[1] * s[0] * s[2],
            -s[1] * s[2] + c[1] * s[0] * c[2],
            c[1] * c[0],
        ),
    )
    .transpose()
}

/// Tungsten's Gram-Schmidt (`JsonPtr.cpp`): `a` normalised, `b` and `c` made orthonormal to
/// what precedes them (falling back to an arbitrary orthogonal vector / a cross product).
fn gram_schmidt(a: &mut DVec3, b: &mut DVec3, c: &mut DVec3) {
    *a = a.normalize_or(DVec3::Z);
    *b -= *a * a.dot(*b);
    *b = if b.length_squared() < 1e-5 {
        a.any_orthonormal_vector()
    } else {
        b.normalize()
    };
    *c -= *a * a.dot(*c);
    *c -= *b * b.dot(*c);
    *c = if c.length_squared() < 1e-5 {
        a.cross(*b)
    } else {
        c.normalize()
    };
}

/// A Tungsten transform (object or 16-number row-major array), as `JsonPtr::get(Mat4f&)`.
pub(crate) fn transform(t: J) -> Result<DMat4, SceneError> {
    if let Some(a) = t.v.as_array() {
        if a.len() != 16 {
            return Err(t.wrong("an object or an array of 16 numbers"));
        }
        let mut m = [0.0f64; 16];
        for (i, v) in a.iter().enumerate() {
            m[i] = J { v, ..t }.f64()?;
        }
        return Ok(DMat4::from_cols_array(&m).transpose());
    }
    t.object()?;
    let get = |k: &str| -> Result<Option<DVec3>, SceneError> {
        t.key(k).map(|v| v.j().dvec3()).transpose()
    };
    let pos = get("position")?.unwrap_or(DVec3::ZERO);
    let (mut x, mut y, mut z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let look_at = get("look_at")?;
    let up = get("up")?;
    let (xa, ya, za) = (get("x_axis")?, get("y_axis")?, get("z_axis")?);
    let ex = xa.is_some();
    let ey = up.is_some() || ya.is_some();
    let ez = look_at.is_some() || za.is_some();
    if let Some(l) = look_at {
        z = l - pos;
    }
    if let Some(u) = up {
        y = u;
    }
    if let Some(v) = xa {
        x = v;
    }
    if let Some(v) = ya {
        y = v;
    }
    if let Some(v) = za {
        z = v;
    }
    if ex || ey || ez {
        match (ez, ey, ex) {
            (false, false, true) => gram_schmidt(&mut x, &mut z, &mut y),
            (false, true, false) => gram_schmidt(&mut y, &mut z, &mut x),
            (false, true, true) => gram_schmidt(&mut y, &mut x, &mut z),
            (true, false, true) => gram_schmidt(&mut z, &mut x, &mut y),
            _ => gram_schmidt(&mut z, &mut y, &mut x),
        }
        if x.cross(y).dot(z) < 0.0 {
            if !ex {
                x = -x;
            } else if !ey {
                y = -y;
            } else {
                z = -z;
            }
        }
    }
    if let Some(s) = get("scale")? {
        x *= s.x;
        y *= s.y;
        z *= s.z;
    }
    if let Some(r) = get("rotation")? {
        let m = rot_yxz(r);
        x = m * x;
        y = m * y;
        z = m * z;
    }
    Ok(DMat4::from_cols(
        x.extend(0.0),
        y.extend(0.0),
        z.extend(0.0),
        pos.extend(1.0),
    ))
}

/// The unit quad's two triangles, front side = Tungsten's `edge1 x edge0`.
pub(crate) fn quad_triangles(m: &DMat4) -> [[Vec3; 3]; 2] {
    let base = m.transform_point3(DVec3::new(-0.5, 0.0, -0.5));
    let e0 = m.transform_vector3(DVec3::X);
    let e1 = m.transform_vector3(DVec3::Z);
    let (p0, p1, p2, p3) = (
        base.as_vec3(),
        (base + e1).as_vec3(),
        (base + e0 + e1).as_vec3(),
        (base + e0).as_vec3(),
    );
    [[p0, p1, p2], [p0, p2, p3]]
}

/// The unit cube's 12 triangles, outward facing: Tungsten's `TriangleMesh::makeCube`, corner
/// for corner and in its triangle order, so that the diagonals match Tungsten's.
pub(crate) fn cube_triangles(m: &DMat4) -> Vec<[Vec3; 3]> {
    const H: f64 = 0.5;
    const FACES: [[[f64; 3]; 4]; 6] = [
        [[-H, -H, -H], [-H, -H, H], [H, -H, H], [H, -H, -H]],
        [[-H, H, H], [-H, H, -H], [H, H, -H], [H, H, H]],
        [[-H, H, -H], [-H, -H, -H], [H, -H, -H], [H, H, -H]],
        [[H, H, H], [H, -H, H], [-H, -H, H], [-H, H, H]],
        [[-H, H, H], [-H, -H, H], [-H, -H, -H], [-H, H, -H]],
        [[H, H, -H], [H, -H, -H], [H, -H, H], [H, H, H]],
    ];
    let mut out = Vec::with_capacity(12);
    for face in &FACES {
        let p = face.map(|c| m.transform_point3(DVec3::from_array(c)).as_vec3());
        out.push([p[0], p[2], p[1]]);
        out.push([p[0], p[3], p[2]]);
    }
    out
}

pub(super) fn area(tris: &[[Vec3; 3]]) -> f32 {
    tris.iter()
        .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec4;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn rot_yxz_is_ry_minus_y_rx_rz() {
        // Tungsten's term-by-term matrix equals the composition Ry(-y) Rx(x) Rz(z) built from
        // glam's own rotations, for a generic angle triple.
        let r = DVec3::new(20.0, 35.0, -50.0);
        let want = DMat3::from_rotation_y(-r.y.to_radians())
            * DMat3::from_rotation_x(r.x.to_radians())
            * DMat3::from_rotation_z(r.z.to_radians());
        assert!(rot_yxz(r).abs_diff_eq(want, 1e-12));
    }

    #[test]
    fn unit_quad_faces_plus_y_and_has_unit_area() {
        let tris = quad_triangles(&DMat4::IDENTITY);
        for [a, b, c] in tris {
            let n = (b - a).cross(c - a);
            assert!(n.normalize().abs_diff_eq(Vec3::Y, 1e-6), "{n}");
        }
        assert!((area(&tris) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn unit_cube_faces_point_outward() {
        let tris = cube_triangles(&DMat4::IDENTITY);
        assert_eq!(tris.len(), 12);
        for [a, b, c] in &tris {
            let n = (*b - *a).cross(*c - *a).normalize();
            let centroid = (*a + *b + *c) / 3.0;
            assert!(n.dot(centroid) > 0.0, "inward face {n} at {centroid}");
        }
        assert!((area(&tris) - 6.0).abs() < 1e-5);
    }

    #[test]
    fn camera_style_transform_is_orthonormal_and_right_handed() {
        let v = serde_json::json!({"position": [0, 1, 6.8], "look_at": [0, 1, 0], "up": [0, 1, 0]});
        let m = transform(J {
            v: &v,
            path: "t",
            file: "f",
        })
        .unwrap();
        let c = |v: DVec4| v.truncate().as_vec3();
        assert!(close(c(m.z_axis), -Vec3::Z));
        assert!(close(c(m.y_axis), Vec3::Y));
        assert!(close(c(m.x_axis), Vec3::Y.cross(-Vec3::Z)));
        assert!(close(c(m.w_axis), Vec3::new(0.0, 1.0, 6.8)));
    }
}
