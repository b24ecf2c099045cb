// Camera rays (camera.rs). Returns the unit direction; the origin is scene.camera_origin.

fn generate_camera_ray(pixel: u32, jitter: vec2<f32>) -> vec3<f32> {
    let x = pixel % scene.width;
    let y = pixel / scene.width;
    let sx = 2.0 * ((f32(x) + jitter.x) / f32(scene.width)) - 1.0;
    let sy = 1.0 - 2.0 * ((f32(y) + jitter.y) / f32(scene.height));
    return normalize(scene.camera_forward + scene.camera_right * sx + scene.camera_up * sy);
}
