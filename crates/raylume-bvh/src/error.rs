//! [`BvhError`]: what can go wrong building a BVH.

use crate::MAX_STACK_DEPTH;

/// Why [`GpuBvh::build`](crate::GpuBvh::build) refused its input.
///
/// The scene crate validates geometry before it gets here; these are the builder's own,
/// defensive checks, so that bad input is an error and never a panic or a silently wrong tree.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum BvhError {
    /// Leaf ranges, node links and scene indices are `u32`, with `u32::MAX` reserved for
    /// [`INVALID_INDEX`](crate::INVALID_INDEX).
    #[error(
        "too many {what} for a BVH with u32 indices: {count} (at most {limit}); split the scene"
    )]
    TooManyPrimitives {
        /// What overflowed: "triangles", "spheres", "primitives (after spatial splits)", "nodes".
        what: &'static str,
        count: usize,
        limit: usize,
    },
    /// A triangle vertex, sphere centre or radius that is NaN or infinite, or whose bounds
    /// overflow `f32`.
    #[error("{kind} {index} has a non-finite coordinate or bound: {detail}")]
    NonFinite {
        /// "triangle" or "sphere".
        kind: &'static str,
        /// Index into the scene's `triangles` or `spheres`.
        index: usize,
        detail: String,
    },
    /// A sphere whose radius is zero or negative.
    #[error("sphere {index} has radius {radius}; a radius must be > 0")]
    BadRadius { index: usize, radius: f32 },
    /// Every build the builder tried (the requested preset, then a balanced median-split
    /// fallback) was deeper than the traversal stack allows. The fallback is at most
    /// `log2(primitives) + 2` deep, so this cannot happen below 2^60 primitives; it is kept
    /// as a check rather than an assumption.
    #[error(
        "the BVH is {depth} levels deep, more than the {max} the GPU traversal stack holds \
         (MAX_STACK_DEPTH)"
    )]
    TooDeep { depth: usize, max: usize },
    /// A tree and primitives that do not belong together (e.g. an LBVH read back from the GPU
    /// for another primitive count: [`GpuBvh::from_lbvh`](crate::GpuBvh::from_lbvh)).
    #[error("inconsistent BVH input: {0}")]
    Inconsistent(String),
}

impl BvhError {
    /// [`BvhError::TooDeep`] for a tree of `depth` levels, or `Ok` if it fits the stack.
    pub(crate) fn check_depth(depth: usize) -> Result<(), BvhError> {
        if depth > MAX_STACK_DEPTH {
            Err(BvhError::TooDeep {
                depth,
                max: MAX_STACK_DEPTH,
            })
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_limit_is_the_stack_size() {
        assert_eq!(BvhError::check_depth(MAX_STACK_DEPTH), Ok(()));
        let err = BvhError::check_depth(MAX_STACK_DEPTH + 1).unwrap_err();
        assert_eq!(
            err,
            BvhError::TooDeep {
                depth: MAX_STACK_DEPTH + 1,
                max: MAX_STACK_DEPTH
            }
        );
        assert!(err.to_string().contains("MAX_STACK_DEPTH"), "{err}");
    }
}
