//! raylume-post: bloom and tone mapping on GPU (WGSL) and CPU (rayon), and image metrics.
