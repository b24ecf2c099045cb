use std::path::PathBuf;

use thiserror::Error;

/// Everything a render can fail with. Each variant wraps the crate that knows the details.
#[derive(Debug, Error)]
pub enum Error {
    /// The scene file could not be loaded or is invalid.
    #[error(transparent)]
    Scene(#[from] raylume_scene::SceneError),
    /// The BVH could not be built.
    #[error(transparent)]
    Bvh(#[from] raylume_bvh::BvhError),
    /// A GPU failure outside the kernels (choosing an adapter, creating the device).
    #[error(transparent)]
    Gpu(#[from] raylume_gpu::GpuError),
    /// The tracer failed (GPU errors during tracing, a scene too large for the adapter).
    #[error(transparent)]
    Kernels(#[from] raylume_kernels::KernelError),
    /// Post-processing failed.
    #[error(transparent)]
    Post(#[from] raylume_post::PostError),
    /// Settings that cannot render (zero sizes, absurd sizes, ...).
    #[error("invalid render settings: {0}")]
    Settings(String),
    /// Render parts that cannot be read or merged (not a part, another render's part, a
    /// missing or overlapping sample range): [`crate::merge`], [`crate::Part::load`].
    #[error("render parts: {0}")]
    Parts(String),
    /// A [`crate::Tracer::target_error`] that is not a finite relative MSE above 0.
    #[error("target error {0}: use a relative MSE above 0 (e.g. 1e-3), a finite number")]
    TargetError(f32),
    /// Writing the output failed; nothing was left at `path`.
    #[error("cannot write {path}: {reason}")]
    Output {
        /// The file that could not be written (empty for an in-memory conversion).
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

impl Error {
    /// True when the GPU device was lost (driver reset, device destroyed). A [`crate::Tracer`]
    /// that meets it drops its GPU context, so its next render runs on a new device.
    pub fn is_device_lost(&self) -> bool {
        use raylume_gpu::GpuError::DeviceLost;
        matches!(
            self,
            Error::Gpu(DeviceLost { .. })
                | Error::Kernels(raylume_kernels::KernelError::Gpu(DeviceLost { .. }))
                | Error::Post(raylume_post::PostError::Gpu(DeviceLost { .. }))
        )
    }
}
