//! raylume-sort: 30-bit origin-direction Morton keys for rays and a radix sort of (key, value) pairs in WGSL, with a CPU reference.
