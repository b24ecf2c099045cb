//! Affine transforms applied to loaded meshes, and the camera that frames a bounding box.

use glam::{DMat3, DVec3, Mat3, Mat4, Vec3};

use crate::model::{Bounds, Camera, Triangle};

/// An affine transform of points, with the matching normal transform: what the loaders apply
/// to meshes (TOML `[[mesh]]`, glTF nodes, Tungsten transforms), public so that scenes built
/// in code (`raylume::SceneBuilder`) place meshes exactly as a file does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Xform {
    /// The point transform.
    pub m: Mat4,
    /// Inverse transpose of the linear part; `None` when the linear part is singular (then
    /// every triangle is degenerate anyway and shading normals are dropped).
    normal: Option<Mat3>,
    /// The linear part mirrors (negative determinant): triangle winding is swapped so that
    /// the front side stays the front side.
    mirrors: bool,
}

impl Xform {
    /// No change.
    pub const IDENTITY: Xform = Xform {
        m: Mat4::IDENTITY,
        normal: Some(Mat3::IDENTITY),
        mirrors: false,
    };

    /// The transform of `m`, its normal matrix and whether it mirrors.
    pub fn from_mat4(m: Mat4) -> Self {
        let linear = Mat3::from_mat4(m);
        let det = linear.determinant();
        let normal = if det != 0.0 && det.is_finite() {
            let n = linear.inverse().transpose();
            n.is_finite().then_some(n)
        } else {
            None
        };
        Xform {
            m,
            normal,
            mirrors: det < 0.0,
        }
    }

    /// The TOML `[[mesh]]` transform: scale, then rotate (degrees about X, then Y, then Z, all
    /// fixed world axes: `R = Rz * Ry * Rx`), then translate.
    pub fn from_srt(scale: Vec3, rotate_deg: Vec3, translate: Vec3) -> Self {
        Self::from_mat4(
            Mat4::from_translation(translate) * rotation_xyz(rotate_deg) * Mat4::from_scale(scale),
        )
    }

    /// Transforms a triangle in place: positions, normals (renormalised; dropped when the
    /// transform is singular), winding (swapped under mirroring).
    pub fn apply(&self, t: &mut Triangle) {
        if self.m == Mat4::IDENTITY {
            return;
        }
        for p in &mut t.positions {
            *p = self.m.transform_point3(*p);
        }
        match (self.normal, t.normals.as_mut()) {
            (Some(nm), Some(ns)) => {
                for n in ns.iter_mut() {
                    let v = nm * *n;
                    let len = v.length();
                    // A finite input normal stays finite unless the transform squashes it to
                    // zero; keep the raw value then so validation/normal checks see it.
                    *n = if len > 0.0 && len.is_finite() {
                        v / len
                    } else {
                        v
                    };
                }
            }
            (None, Some(_)) => t.normals = None,
            _ => {}
        }
        if self.mirrors {
            t.positions.swap(1, 2);
            if let Some(n) = t.normals.as_mut() {
                n.swap(1, 2);
            }
            if let Some(uv) = t.uvs.as_mut() {
                uv.swap(1, 2);
            }
        }
    }
}

/// Sine and cosine of an angle in degrees, exact at multiples of 90 degrees (so that a scene
/// rotated by right angles lands exactly on the grid it was modelled on).
pub(crate) fn sin_cos_deg(deg: f64) -> (f64, f64) {
    let r = deg.rem_euclid(360.0);
    if r % 90.0 == 0.0 {
        match (r / 90.0) as i32 {
            0 => (0.0, 1.0),
            1 => (1.0, 0.0),
            2 => (0.0, -1.0),
            _ => (-1.0, 0.0),
        }
    } else {
        let x = deg.to_radians();
        (x.sin(), x.cos())
    }
}

fn rot_x(deg: f64) -> DMat3 {
    let (s, c) = sin_cos_deg(deg);
    DMat3::from_cols(DVec3::X, DVec3::new(0.0, c, s), DVec3::new(0.0, -s, c))
}

fn rot_y(deg: f64) -> DMat3 {
    let (s, c) = sin_cos_deg(deg);
    DMat3::from_cols(DVec3::new(c, 0.0, -s), DVec3::Y, DVec3::new(s, 0.0, c))
}

fn rot_z(deg: f64) -> DMat3 {
    let (s, c) = sin_cos_deg(deg);
    DMat3::from_cols(DVec3::new(c, s, 0.0), DVec3::new(-s, c, 0.0), DVec3::Z)
}

/// Rotation by `deg` degrees about X, then Y, then Z (fixed axes): `Rz * Ry * Rx`, in double
/// precision, exact for right angles.
pub(crate) fn rotation_xyz(deg: Vec3) -> Mat4 {
    let d = deg.as_dvec3();
    Mat4::from_mat3((rot_z(d.z) * rot_y(d.y) * rot_x(d.x)).as_mat3())
}

/// Vertical field of view of a framing camera, degrees.
pub(crate) const FRAMING_VFOV: f32 = 40.0;

/// A camera on the +z side of `bounds`, looking down -z at its centre, far enough that the
/// bounding sphere fits a `FRAMING_VFOV` view (so the box fits whatever the aspect ratio is,
/// as long as the image is at least as wide as it is tall).
pub(crate) fn frame_bounds(bounds: Bounds) -> Camera {
    if bounds.is_empty() {
        return Camera::default();
    }
    let center = (bounds.min + bounds.max) * 0.5;
    let radius = (bounds.max - bounds.min).length() * 0.5;
    let half = (FRAMING_VFOV * 0.5).to_radians();
    let distance = if radius > 0.0 && radius.is_finite() {
        radius / half.sin()
    } else {
        1.0
    };
    Camera {
        position: center + Vec3::new(0.0, 0.0, distance),
        look_at: center,
        up: Vec3::Y,
        fov: FRAMING_VFOV,
        fov_axis: crate::model::FovAxis::Vertical,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn rotation_order_is_x_then_y_then_z() {
        // Worked by hand: Rx(90) keeps +x; Ry(90) sends +x to -z. Rx(90) sends +y to +z;
        // Ry(90) sends +z to +x.
        let r = rotation_xyz(Vec3::new(90.0, 90.0, 0.0));
        assert!(close(r.transform_vector3(Vec3::X), -Vec3::Z));
        assert!(close(r.transform_vector3(Vec3::Y), Vec3::X));
        // Rz alone: +x to +y.
        let r = rotation_xyz(Vec3::new(0.0, 0.0, 90.0));
        assert!(close(r.transform_vector3(Vec3::X), Vec3::Y));
    }

    #[test]
    fn right_angles_are_exact_and_others_match_glam() {
        let r = rotation_xyz(Vec3::new(90.0, 180.0, -270.0));
        for v in r.to_cols_array() {
            assert!(v == 0.0 || v == 1.0 || v == -1.0, "{v}");
        }
        let d = Vec3::new(17.0, -33.0, 71.0);
        let glam = Mat4::from_rotation_z(d.z.to_radians())
            * Mat4::from_rotation_y(d.y.to_radians())
            * Mat4::from_rotation_x(d.x.to_radians());
        assert!(rotation_xyz(d).abs_diff_eq(glam, 1e-6));
    }

    #[test]
    fn scale_then_rotate_then_translate() {
        let x = Xform::from_srt(
            Vec3::new(2.0, 1.0, 1.0),
            Vec3::new(0.0, 0.0, 90.0),
            Vec3::new(10.0, 0.0, 0.0),
        );
        // (1,0,0) -> scale (2,0,0) -> rotate z 90 (0,2,0) -> translate (10,2,0).
        assert!(close(
            x.m.transform_point3(Vec3::X),
            Vec3::new(10.0, 2.0, 0.0)
        ));
    }

    #[test]
    fn normals_use_inverse_transpose_and_mirrors_keep_the_front() {
        // A triangle in the plane x + y = 1 scaled by 2 in x: its normal is not the scaled
        // normal but (1/2, 1, 0) normalised.
        let mut t = Triangle {
            positions: [
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            normals: Some([Vec3::new(1.0, 1.0, 0.0).normalize(); 3]),
            uvs: None,
            material: 0,
        };
        Xform::from_srt(Vec3::new(2.0, 1.0, 1.0), Vec3::ZERO, Vec3::ZERO).apply(&mut t);
        let want = Vec3::new(0.5, 1.0, 0.0).normalize();
        assert!(close(t.normals.unwrap()[0], want));
        let [a, b, c] = t.positions;
        let geo = (b - a).cross(c - a).normalize();
        assert!(geo.dot(want) > 0.99);

        // Mirror in x: the geometric normal must still agree with the shading normal.
        let mut m = t;
        Xform::from_srt(Vec3::new(-1.0, 1.0, 1.0), Vec3::ZERO, Vec3::ZERO).apply(&mut m);
        let [a, b, c] = m.positions;
        let geo = (b - a).cross(c - a).normalize();
        assert!(geo.dot(m.normals.unwrap()[0]) > 0.99);
    }

    #[test]
    fn framing_sees_the_whole_box() {
        let b = Bounds {
            min: Vec3::new(-1.0, 0.0, -3.0),
            max: Vec3::new(3.0, 2.0, 1.0),
        };
        let cam = frame_bounds(b);
        assert_eq!(cam.look_at, Vec3::new(1.0, 1.0, -1.0));
        let dir = (cam.look_at - cam.position).normalize();
        assert!(close(dir, -Vec3::Z));
        // Every corner lies within the vertical half-angle of the view axis.
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            let to = (c - cam.position).normalize();
            assert!(to.dot(dir) >= (FRAMING_VFOV * 0.5).to_radians().cos() - 1e-6);
        }
    }
}
