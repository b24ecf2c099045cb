//! Issue 19's synthetic large scene: a height field of `n` x `n` quads over the unit square,
//! two triangles each, heights a smooth deterministic function (a terrain-like surface). The
//! sizes measured: 224 (100,352 triangles), 707 (999,698), 1224 (2,996,352). The benches
//! build their trees over it, and the `make_grid` example writes it as OBJ (the same
//! vertices, printed with 6 decimals) for loading and for Mitsuba.

use glam::Vec3;

use crate::model::Triangle;

/// The height of vertex `(i, j)` (`0..=n` each) of an `n`-quad grid.
pub fn height(n: usize, i: usize, j: usize) -> f32 {
    let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
    0.05 * (12.0 * x).sin() * (9.0 * z).cos() + 0.02 * (31.0 * x + 17.0 * z).sin()
}

/// Vertex `(i, j)` of an `n`-quad grid: `(i / n, height, j / n)`.
pub fn vertex(n: usize, i: usize, j: usize) -> Vec3 {
    Vec3::new(i as f32 / n as f32, height(n, i, j), j as f32 / n as f32)
}

/// The grid's `2 n^2` triangles (material 0), row by row: quad `(i, j)` as
/// `(i,j) (i+1,j) (i+1,j+1)` and `(i,j) (i+1,j+1) (i,j+1)`.
pub fn height_field(n: usize) -> Vec<Triangle> {
    let p = |i: usize, j: usize| vertex(n, i, j);
    let mut out = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            out.push(Triangle::flat([a, b, c], 0));
            out.push(Triangle::flat([a, c, d], 0));
        }
    }
    out
}
