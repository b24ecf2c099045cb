use raylume_gpu::GpuError;
use thiserror::Error;

/// What can go wrong while preparing or running a render.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum KernelError {
    /// A GPU failure (no adapter, validation, out of memory, device lost, ...).
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// Some scene data does not fit one storage binding of the adapter.
    #[error(
        "the scene is too large for the GPU adapter `{adapter}`: {what} needs {bytes} bytes in \
         one buffer, but the adapter allows at most {limit} bytes per storage buffer; use a \
         smaller scene or texture, or the CPU backend"
    )]
    SceneTooLarge {
        what: String,
        bytes: u64,
        limit: u64,
        adapter: String,
    },
    /// The scene's data is inconsistent with itself or with its BVH.
    #[error("invalid scene for the tracer: {0}")]
    InvalidScene(String),
    /// A BVH could not be built (e.g. on the GPU: a tree deeper than the traversal's stack).
    #[error(transparent)]
    Bvh(#[from] raylume_bvh::BvhError),
    /// The settings cannot be rendered.
    #[error("invalid trace settings: {0}")]
    InvalidSettings(String),
}

impl KernelError {
    /// Turns a buffer that did not fit into [`KernelError::SceneTooLarge`]; other GPU errors
    /// pass through.
    pub(crate) fn from_upload(e: GpuError) -> Self {
        match e {
            GpuError::TooLarge {
                what,
                bytes,
                limit,
                adapter,
            } => KernelError::SceneTooLarge {
                what,
                bytes,
                limit,
                adapter,
            },
            other => KernelError::Gpu(other),
        }
    }
}

/// A ray sorter's failure: its GPU errors as the tracer's, anything else (a sorter asked for
/// what it cannot do) as invalid settings.
impl From<raylume_sort::SortError> for KernelError {
    fn from(e: raylume_sort::SortError) -> Self {
        match e {
            raylume_sort::SortError::Gpu(g) => KernelError::Gpu(g),
            other => KernelError::InvalidSettings(format!("ray sorting: {other}")),
        }
    }
}
