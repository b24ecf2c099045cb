//! raylume-kernels: the WGSL kernels (raygen, propagate, resolve), their wgpu pipelines, and the CPU mirror of the same functions in Rust.
