//! Bounding boxes of [`Primitive`]s, shared by the builder, the flattener and `validate`.

use glam::Vec3A;
use obvhs::aabb::Aabb;
use rayon::prelude::*;

use raylume_scene::{Sphere, Triangle};

use crate::{PRIM_SPHERE, Primitive};

/// The box the BVH must enclose for `p`: the exact vertex bounds of a triangle; for a sphere,
/// centre ± radius widened by 2 ulp of the largest magnitude involved, so that rounding in
/// `centre - radius` never cuts the sphere (a box a hair too large costs nothing; one a hair
/// too small loses grazing hits).
pub(crate) fn primitive_aabb(p: &Primitive) -> Aabb {
    let a = Vec3A::new(p.a[0], p.a[1], p.a[2]);
    if p.kind() == PRIM_SPHERE {
        let r = p.a[3];
        let slack = (a.abs() + Vec3A::splat(r)) * (2.0 * f32::EPSILON);
        Aabb::new(a - Vec3A::splat(r) - slack, a + Vec3A::splat(r) + slack)
    } else {
        let b = Vec3A::new(p.b[0], p.b[1], p.b[2]);
        let c = Vec3A::new(p.c[0], p.c[1], p.c[2]);
        Aabb::new(a.min(b).min(c), a.max(b).max(c))
    }
}

/// True when `outer` contains `inner` (boundaries inclusive).
pub(crate) fn contains(outer: &Aabb, inner: &Aabb) -> bool {
    outer.min.cmple(inner.min).all() && outer.max.cmpge(inner.max).all()
}

/// Half the surface area, 0 for an empty (inverted) box.
pub(crate) fn half_area(b: &Aabb) -> f32 {
    let d = (b.max - b.min).max(Vec3A::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// The primitives a build is over, made on demand from the scene's triangles and spheres
/// (triangles first, then spheres; [`Source::get`]`(i)` is primitive `i`): a large scene's
/// build holds no copy of them (3M triangles: 144 MB of `Primitive`s, fresh pages that cost
/// ~0.1 s on the 2-core machine before anything was computed).
#[derive(Clone, Copy)]
pub(crate) struct Source<'a> {
    pub triangles: &'a [Triangle],
    pub spheres: &'a [Sphere],
}

impl Source<'_> {
    /// Primitives: triangles and spheres.
    pub fn len(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    /// Primitive `i` (`i < len()`), its scene index that of its triangle or sphere.
    pub fn get(&self, i: u32) -> Primitive {
        let i = i as usize;
        match self.triangles.get(i) {
            Some(t) => Primitive::triangle(t.positions.map(|p| p.to_array()), i as u32),
            None => {
                let k = i - self.triangles.len();
                let s = &self.spheres[k];
                Primitive::sphere(s.center.to_array(), s.radius, k as u32)
            }
        }
    }

    /// [`primitive_aabb`] of primitive `i`.
    pub fn aabb(&self, i: u32) -> Aabb {
        primitive_aabb(&self.get(i))
    }

    /// Every primitive's box, in order, on every core.
    pub fn aabbs(&self) -> Vec<Aabb> {
        (0..self.len() as u32)
            .into_par_iter()
            .map(|i| self.aabb(i))
            .collect()
    }

    /// `made` when it holds every box (a build that made them), else [`Source::aabbs`].
    pub fn boxes<'b>(&self, made: &'b [Aabb]) -> std::borrow::Cow<'b, [Aabb]> {
        if made.len() == self.len() {
            std::borrow::Cow::Borrowed(made)
        } else {
            std::borrow::Cow::Owned(self.aabbs())
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::{PRIM_TRIANGLE, Primitive};

    /// Triangles then spheres, each with its own scene index, boxes as the primitives' own;
    /// the fallbacks' `boxes` borrows a complete array and makes a missing one.
    #[test]
    fn the_source_is_the_scene_in_order() {
        let triangles: Vec<Triangle> = (0..5)
            .map(|i| {
                let o = Vec3::splat(i as f32);
                Triangle::flat([o, o + Vec3::X, o + Vec3::Y * 2.0], 0)
            })
            .collect();
        let spheres = vec![Sphere {
            center: Vec3::new(1.0, -2.0, 3.0),
            radius: 0.5,
            material: 0,
        }];
        let source = Source {
            triangles: &triangles,
            spheres: &spheres,
        };
        assert_eq!(source.len(), 6);
        for (i, t) in triangles.iter().enumerate() {
            let p = source.get(i as u32);
            assert_eq!((p.kind(), p.scene_index()), (PRIM_TRIANGLE, i as u32));
            assert_eq!(
                p,
                Primitive::triangle(t.positions.map(|v| v.to_array()), i as u32)
            );
        }
        let s = source.get(5);
        assert_eq!((s.kind(), s.scene_index()), (PRIM_SPHERE, 0));
        let made = source.aabbs();
        let by_one: Vec<Aabb> = (0..6).map(|i| primitive_aabb(&source.get(i))).collect();
        assert_eq!(made, by_one);
        assert!(matches!(source.boxes(&made), std::borrow::Cow::Borrowed(_)));
        assert_eq!(*source.boxes(&[]), made[..]);
    }
}
