//! Camera rays (`camera.wgsl` is the same function in WGSL).

use glam::{Vec2, Vec3};
use raylume_scene::Camera;

use crate::gpu_types::SceneUniforms;
use crate::math::normalize;

/// The camera basis as [`SceneUniforms`] stores it: origin, forward, and right/up pre-scaled
/// so that the image spans `[-1, 1]` along each. The field of view spans the camera's own
/// axis ([`Camera::fov_axis`]); the other follows from `width / height`.
pub fn camera_basis(camera: &Camera, width: u32, height: u32) -> [Vec3; 4] {
    let forward = normalize(camera.look_at - camera.position);
    let right = normalize(forward.cross(camera.up));
    let up = right.cross(forward);
    let (half_width, half_height) = camera.half_extent(width, height);
    [
        camera.position,
        forward,
        right * half_width,
        up * half_height,
    ]
}

/// The primary ray through pixel `pixel` (row-major, top row first) at sub-pixel offset
/// `jitter` in `[0, 1)²`: returns its unit direction (the origin is `camera_origin`).
#[inline]
pub fn generate_camera_ray(u: &SceneUniforms, pixel: u32, jitter: Vec2) -> Vec3 {
    let x = pixel % u.width;
    let y = pixel / u.width;
    let sx = 2.0 * ((x as f32 + jitter.x) / u.width as f32) - 1.0;
    let sy = 1.0 - 2.0 * ((y as f32 + jitter.y) / u.height as f32);
    let forward = Vec3::from(u.camera_forward);
    let right = Vec3::from(u.camera_right);
    let up = Vec3::from(u.camera_up);
    normalize(forward + right * sx + up * sy)
}

/// The WGSL source of [`generate_camera_ray`].
pub const CAMERA_WGSL: &str = include_str!("camera.wgsl");

#[cfg(test)]
mod tests {
    use super::*;
    use raylume_scene::FovAxis;

    fn uniforms(camera: &Camera, w: u32, h: u32) -> SceneUniforms {
        let [o, f, r, up] = camera_basis(camera, w, h);
        SceneUniforms {
            camera_origin: o.into(),
            camera_forward: f.into(),
            camera_right: r.into(),
            camera_up: up.into(),
            width: w,
            height: h,
            ..Default::default()
        }
    }

    #[test]
    fn image_corners_span_the_field_of_view() {
        let cam = Camera {
            position: Vec3::new(0.0, 1.0, 5.0),
            look_at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov: 90.0,
            fov_axis: FovAxis::Vertical,
        };
        let u = uniforms(&cam, 200, 100);
        // Top-left corner of the top-left pixel: up 45 degrees, left atan(2 * tan 45).
        let d = generate_camera_ray(&u, 0, Vec2::ZERO);
        assert_eq!(Vec3::from(u.camera_origin), cam.position);
        let expected = Vec3::new(-2.0, 1.0, -1.0).normalize();
        assert!((d - expected).length() < 1e-6, "{d} vs {expected}");
        // Centre of the image looks at look_at.
        let d = generate_camera_ray(&u, 50 * 200 + 100, Vec2::ZERO);
        assert!((d - Vec3::NEG_Z).length() < 1e-6, "{d}");
        // Bottom-right corner.
        let d = generate_camera_ray(&u, 200 * 100 - 1, Vec2::splat(0.999_999_9));
        let expected = Vec3::new(2.0, -1.0, -1.0).normalize();
        assert!((d - expected).length() < 1e-5, "{d} vs {expected}");
    }

    #[test]
    fn the_fov_keeps_its_axis_at_any_aspect() {
        // A horizontal fov of 90 degrees spans the width at every size: at 100x200 (tall) the
        // left edge is 45 degrees off the axis and the top edge atan(2); at 200x100 the top is
        // atan(1/2). A vertical fov spans the height instead.
        for (fov_axis, w, h, corner) in [
            (FovAxis::Horizontal, 100, 200, Vec3::new(-1.0, 2.0, -1.0)),
            (FovAxis::Horizontal, 200, 100, Vec3::new(-1.0, 0.5, -1.0)),
            (FovAxis::Vertical, 100, 200, Vec3::new(-0.5, 1.0, -1.0)),
            (FovAxis::Vertical, 200, 100, Vec3::new(-2.0, 1.0, -1.0)),
        ] {
            let cam = Camera {
                position: Vec3::ZERO,
                look_at: Vec3::NEG_Z,
                up: Vec3::Y,
                fov: 90.0,
                fov_axis,
            };
            let d = generate_camera_ray(&uniforms(&cam, w, h), 0, Vec2::ZERO);
            let expected = corner.normalize();
            assert!(
                (d - expected).length() < 1e-6,
                "{fov_axis:?} {w}x{h}: {d} vs {expected}"
            );
            let vfov = 2.0 * corner.y.atan().to_degrees();
            assert!((cam.vfov(w, h) - vfov).abs() < 1e-4);
        }
    }
}
