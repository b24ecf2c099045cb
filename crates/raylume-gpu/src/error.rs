use thiserror::Error;

/// Everything that can go wrong on the GPU side, phrased for the person who has to act on it.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GpuError {
    /// No adapter matched. `tried` lists what wgpu offered, so the message says what exists.
    #[error(
        "no GPU adapter found ({tried}); install a Vulkan driver (on Debian: \
         `apt-get install mesa-vulkan-drivers libvulkan1` gives a CPU one) or use the CPU backend"
    )]
    NoAdapter {
        /// The adapters that were seen and rejected, or "none".
        tried: String,
    },
    /// The adapter refused to create a device.
    #[error("the GPU adapter `{adapter}` refused to create a device: {reason}")]
    RequestDevice { adapter: String, reason: String },
    /// A single buffer would exceed what the adapter allows.
    #[error(
        "{what} needs {bytes} bytes in one GPU buffer, but the adapter `{adapter}` allows at most \
         {limit} bytes per storage binding; use a smaller scene, fewer samples per batch, or the \
         CPU backend"
    )]
    TooLarge {
        what: String,
        bytes: u64,
        limit: u64,
        adapter: String,
    },
    /// The driver ran out of memory.
    #[error("the GPU ran out of memory during {during}: {detail}")]
    OutOfMemory { during: String, detail: String },
    /// wgpu rejected what raylume asked for (a shader, a binding, a dispatch). A bug in raylume
    /// or a limit of this adapter: the message names which operation.
    #[error("GPU validation error during {during}: {detail}")]
    Validation { during: String, detail: String },
    /// An internal driver error.
    #[error("GPU internal error during {during}: {detail}")]
    Internal { during: String, detail: String },
    /// The device was lost (driver reset, GPU hang, device destroyed).
    #[error("the GPU device was lost during {during}: {detail}; re-run, or use the CPU backend")]
    DeviceLost { during: String, detail: String },
    /// Waiting for the GPU failed or timed out.
    #[error("waiting for the GPU failed during {during}: {detail}")]
    Poll { during: String, detail: String },
    /// Reading a buffer back to the CPU failed.
    #[error("reading GPU results back failed during {during}: {detail}")]
    Map { during: String, detail: String },
}

impl GpuError {
    /// Converts a wgpu error caught in an error scope.
    pub fn from_wgpu(during: &str, err: wgpu::Error) -> Self {
        let during = during.to_string();
        match err {
            wgpu::Error::OutOfMemory { source } => GpuError::OutOfMemory {
                during,
                detail: source.to_string(),
            },
            wgpu::Error::Validation { description, .. } => GpuError::Validation {
                during,
                detail: description,
            },
            wgpu::Error::Internal { description, .. } => GpuError::Internal {
                during,
                detail: description,
            },
        }
    }
}
