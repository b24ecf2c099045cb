//! raylume: the facade. A `Tracer` that loads nothing itself but ties scene, BVH, kernels, sorting and post-processing into batched renders on the GPU or the CPU.
