use raylume_gpu::GpuError;
use thiserror::Error;

/// What can go wrong when sorting on the GPU.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SortError {
    /// A GPU failure (no adapter, a buffer over the adapter's limits, validation, device loss).
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// More pairs than the sorter was created for.
    #[error("cannot sort {len} pairs: this RadixSorter was created for at most {max_len}")]
    TooLong { len: u64, max_len: u32 },
    /// Keys and values of different lengths.
    #[error("sort_pairs got {keys} keys but {values} values; they must be equally long")]
    LengthMismatch { keys: usize, values: usize },
    /// Options out of their documented ranges, or a combination the adapter cannot run.
    #[error("invalid sort options: {0}")]
    InvalidOptions(String),
    /// A buffer handed to `RadixSorter::encode` is too small or lacks a usage.
    #[error("the {which} buffer handed to RadixSorter::encode {problem}")]
    BadBuffer {
        which: &'static str,
        problem: String,
    },
}
