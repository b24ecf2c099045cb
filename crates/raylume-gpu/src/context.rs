use std::sync::{Arc, Mutex};

use wgpu::util::DeviceExt;

use crate::GpuError;

/// Which adapters [`GpuContext::new`] may pick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AdapterChoice {
    /// Hardware adapters only (discrete, integrated or virtual GPUs). This is what the
    /// `Auto` backend uses: on a machine whose only adapter is a software rasteriser such as
    /// lavapipe, raylume's own CPU path is the faster choice.
    HardwareOnly,
    /// Any adapter, software ones (lavapipe, `DeviceType::Cpu`) included, still ranked
    /// hardware first. What an explicit `--backend gpu` and the tests use.
    #[default]
    Any,
}

/// Options for [`GpuContext::new`]. `Copy`-free because of the name filter; cheap to clone.
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Which adapters qualify.
    pub choice: AdapterChoice,
    /// Keep only adapters whose name contains this text (case-insensitive). `None` reads the
    /// environment variable `RAYLUME_ADAPTER`, if set.
    pub adapter_name: Option<String>,
}

/// What was picked, for logs and the `--stats` JSON.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuInfo {
    /// Adapter name as the driver reports it, e.g. `NVIDIA H100 80GB HBM3` or `llvmpipe (...)`.
    pub name: String,
    /// `Vulkan`, `Gl`, ...
    pub backend: String,
    /// `DiscreteGpu`, `Cpu`, ...
    pub device_type: String,
    /// Driver name and version.
    pub driver: String,
    /// True for software adapters (lavapipe and the like).
    pub is_software: bool,
}

/// A wgpu device and queue with the adapter's limits, the optional features raylume uses, and
/// typed error capture. Cheap to share by reference; all methods take `&self`. A clone is
/// the same device (wgpu's handles and the error state are shared), for another thread.
#[derive(Clone)]
pub struct GpuContext {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: GpuInfo,
    /// The limits the device was created with: the adapter's own, not wgpu's defaults.
    pub limits: wgpu::Limits,
    /// The features the device was created with (a subset of [`GpuContext::WANTED_FEATURES`]).
    pub features: wgpu::Features,
    lost: Arc<Mutex<Option<String>>>,
    uncaptured: Arc<Mutex<Option<wgpu::Error>>>,
}

/// The adapters of the first backend that has any, in [`backend_order`].
fn enumerate_adapters() -> Vec<wgpu::Adapter> {
    for backends in backend_order() {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = backends;
        // wgpu re-validates every indirect dispatch with an extra compute pass (~40 us
        // per radix sort on the H100, about 90 indirect dispatches per sorted batch).
        // raylume's indirect arguments all come from its own kernels (`prepare_propagate`,
        // `sort_setup`), which clamp them to the device's limits, so the check is left
        // out; `WGPU_VALIDATION_INDIRECT_CALL=1` turns it back on.
        let mut flags = wgpu::InstanceFlags::from_build_config();
        flags.remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
        desc.flags = flags.with_env();
        let instance = wgpu::Instance::new(desc);
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        if !adapters.is_empty() {
            return adapters;
        }
    }
    Vec::new()
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("info", &self.info)
            .finish()
    }
}

fn type_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

fn backend_rank(b: wgpu::Backend) -> u32 {
    match b {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    }
}

impl GpuContext {
    /// Optional features raylume uses when the adapter has them.
    pub const WANTED_FEATURES: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY
        .union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS)
        .union(wgpu::Features::SUBGROUP);

    /// The environment variable [`GpuContext::new`] reads for a lower storage-binding limit
    /// (in bytes) than the adapter's: the device is then created with
    /// `max_storage_buffer_binding_size = min(adapter's, this)`, so every binding past it is
    /// refused as on an adapter that small (see [`GpuContext::new_with_binding_limit`]). What
    /// the tests use to provoke "too large for a binding" through the `render` command on any
    /// adapter; unset, the adapter's own limit holds.
    pub const MAX_BINDING_ENV: &'static str = "RAYLUME_MAX_BINDING_BYTES";

    /// Picks the best adapter allowed by `opts` (discrete GPU first, then integrated, virtual,
    /// other, software; Vulkan/Metal/DX12 before GL) and creates a device with the adapter's
    /// full limits (the storage-binding limit lowered to [`GpuContext::MAX_BINDING_ENV`] when
    /// that is set).
    pub fn new(opts: &ContextOptions) -> Result<Self, GpuError> {
        Self::new_announcing(opts, |_| ())
    }

    /// [`GpuContext::new`], telling `chosen` which adapter it picked (`None`: none qualified)
    /// as soon as it knows, before it creates the device (on the H200 about half of the
    /// 0.15 s `new` takes): a caller on another thread can plan by the adapter's kind
    /// meanwhile (`raylume`'s `Tracer::prepare_scene` does).
    pub fn new_announcing(
        opts: &ContextOptions,
        chosen: impl FnOnce(Option<&wgpu::AdapterInfo>),
    ) -> Result<Self, GpuError> {
        let cap = match std::env::var(Self::MAX_BINDING_ENV) {
            Err(_) => None,
            Ok(v) => Some(
                v.trim()
                    .parse::<u64>()
                    .map_err(|_| GpuError::RequestDevice {
                        adapter: "(none chosen yet)".into(),
                        reason: format!("{}={v:?} is not a number of bytes", Self::MAX_BINDING_ENV),
                    })?,
            ),
        };
        Self::open(opts, cap, chosen)
    }

    /// [`GpuContext::new`] with the storage-binding limit lowered to at most
    /// `max_binding_bytes` (rounded down to a multiple of 4; `None`: the adapter's own). The
    /// device itself is created with the lower limit, so wgpu enforces it as well as
    /// [`GpuContext::check_fits`]. For tests of the "too large" paths on adapters whose own
    /// limit is too large to build such a scene (an H100 or H200: 2 GiB per binding). Ignores
    /// [`GpuContext::MAX_BINDING_ENV`].
    pub fn new_with_binding_limit(
        opts: &ContextOptions,
        max_binding_bytes: Option<u64>,
    ) -> Result<Self, GpuError> {
        Self::open(opts, max_binding_bytes, |_| ())
    }

    /// [`GpuContext::new_with_binding_limit`], announcing the adapter to `chosen` before the
    /// device is created.
    fn open(
        opts: &ContextOptions,
        max_binding_bytes: Option<u64>,
        chosen: impl FnOnce(Option<&wgpu::AdapterInfo>),
    ) -> Result<Self, GpuError> {
        // Vulkan/Metal/DX12 first; GL only when they offer nothing (initialising EGL prints
        // noise on headless machines and is never the better choice).
        let adapters = enumerate_adapters();
        let name_filter = opts
            .adapter_name
            .clone()
            .or_else(|| std::env::var("RAYLUME_ADAPTER").ok())
            .map(|s| s.to_lowercase());
        let seen: Vec<String> = adapters
            .iter()
            .map(|a| {
                let i = a.get_info();
                format!("{} [{:?}, {:?}]", i.name, i.backend, i.device_type)
            })
            .collect();
        let mut candidates: Vec<wgpu::Adapter> = adapters
            .into_iter()
            .filter(|a| {
                let i = a.get_info();
                let type_ok =
                    opts.choice == AdapterChoice::Any || i.device_type != wgpu::DeviceType::Cpu;
                let name_ok = name_filter
                    .as_ref()
                    .is_none_or(|f| i.name.to_lowercase().contains(f.as_str()));
                type_ok && name_ok
            })
            .collect();
        candidates.sort_by_key(|a| {
            let i = a.get_info();
            (type_rank(i.device_type), backend_rank(i.backend))
        });
        let adapter = candidates.into_iter().next();
        chosen(adapter.as_ref().map(|a| a.get_info()).as_ref());
        let Some(adapter) = adapter else {
            let tried = if seen.is_empty() {
                match std::env::var("WGPU_BACKEND") {
                    // The usual cause then: a backend this machine does not have.
                    Ok(b) => format!(
                        "wgpu saw no adapter at all; WGPU_BACKEND={b} limits it to those backends"
                    ),
                    Err(_) => "wgpu saw no adapter at all".to_string(),
                }
            } else {
                format!("seen but not allowed: {}", seen.join("; "))
            };
            return Err(GpuError::NoAdapter { tried });
        };
        Self::from_adapter_with_binding_limit(adapter, max_binding_bytes)
    }

    /// A context on **every** adapter `opts` allows (best first, as [`GpuContext::new`] ranks
    /// them): the devices of a several-GPU render. The adapters of the first backend that has
    /// any (Vulkan before GL), as `new` looks; an error when there is none.
    pub fn all(opts: &ContextOptions) -> Result<Vec<Self>, GpuError> {
        let adapters = enumerate_adapters();
        let name_filter = opts.adapter_name.as_ref().map(|s| s.to_lowercase());
        let mut chosen: Vec<wgpu::Adapter> = adapters
            .into_iter()
            .filter(|a| {
                let i = a.get_info();
                (opts.choice == AdapterChoice::Any || i.device_type != wgpu::DeviceType::Cpu)
                    && name_filter
                        .as_ref()
                        .is_none_or(|f| i.name.to_lowercase().contains(f.as_str()))
            })
            .collect();
        chosen.sort_by_key(|a| {
            let i = a.get_info();
            (type_rank(i.device_type), backend_rank(i.backend))
        });
        if chosen.is_empty() {
            return Err(GpuError::NoAdapter {
                tried: "no adapter of the kind asked for".into(),
            });
        }
        chosen.into_iter().map(Self::from_adapter).collect()
    }

    /// Creates the device on a given adapter, with the adapter's full limits.
    pub fn from_adapter(adapter: wgpu::Adapter) -> Result<Self, GpuError> {
        Self::from_adapter_with_binding_limit(adapter, None)
    }

    /// Creates the device on a given adapter, its storage-binding limit lowered to at most
    /// `max_binding_bytes` (see [`GpuContext::new_with_binding_limit`]).
    pub fn from_adapter_with_binding_limit(
        adapter: wgpu::Adapter,
        max_binding_bytes: Option<u64>,
    ) -> Result<Self, GpuError> {
        let ai = adapter.get_info();
        let mut limits = adapter.limits();
        if let Some(cap) = max_binding_bytes {
            limits.max_storage_buffer_binding_size =
                limits.max_storage_buffer_binding_size.min(cap & !3);
        }
        let features = adapter.features() & Self::WANTED_FEATURES;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("raylume"),
            required_features: features,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::RequestDevice {
            adapter: ai.name.clone(),
            reason: e.to_string(),
        })?;
        let lost = Arc::new(Mutex::new(None));
        let lost_cb = lost.clone();
        device.set_device_lost_callback(move |reason, msg| {
            if let Ok(mut l) = lost_cb.lock() {
                *l = Some(format!("{reason:?}: {msg}"));
            }
        });
        let uncaptured = Arc::new(Mutex::new(None));
        let uncaptured_cb = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut u) = uncaptured_cb.lock() {
                u.get_or_insert(e);
            }
        }));
        let info = GpuInfo {
            name: ai.name.clone(),
            backend: format!("{:?}", ai.backend),
            device_type: format!("{:?}", ai.device_type),
            driver: format!("{} {}", ai.driver, ai.driver_info)
                .trim()
                .to_string(),
            is_software: ai.device_type == wgpu::DeviceType::Cpu,
        };
        Ok(Self {
            adapter,
            device,
            queue,
            info,
            limits,
            features,
            lost,
            uncaptured,
        })
    }

    /// One line naming the adapter, for logs: `NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu)`.
    pub fn describe(&self) -> String {
        format!(
            "{} ({}, {})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    /// True when pass-boundary timestamps can be written.
    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// True when WGSL subgroup builtins may be used.
    pub fn has_subgroups(&self) -> bool {
        self.features.contains(wgpu::Features::SUBGROUP)
    }

    /// Compiles WGSL into a shader module.
    ///
    /// On Vulkan, wgpu turns on `robustBufferAccess` (a feature every conformant Vulkan
    /// driver has) and `robustBufferAccess2` where present, so an out-of-range buffer access
    /// stays inside its buffer whatever the shader does. There raylume leaves out naga's own
    /// bounds checks and loop bounding: the loops of raylume's shaders are bounded by
    /// construction (traversal by the tree, paths by `max_bounces`), and the only private
    /// array indexed dynamically, the BVH stack, cannot overflow (`raylume-bvh` rejects trees
    /// deeper than its size). Measured on the H100: 4-11 % faster renders (docs/RESULTS.md).
    /// On every other backend the checks stay.
    pub fn shader_module(&self, label: &str, wgsl: &str) -> wgpu::ShaderModule {
        let desc = wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(wgsl.into()),
        };
        if self.adapter.get_info().backend == wgpu::Backend::Vulkan {
            // SAFETY: see above: Vulkan's robust buffer access keeps buffer accesses in
            // bounds, and raylume's loops and private-array indices are bounded.
            unsafe {
                self.device
                    .create_shader_module_trusted(desc, wgpu::ShaderRuntimeChecks::unchecked())
            }
        } else {
            self.device.create_shader_module(desc)
        }
    }

    /// The largest storage buffer binding, in bytes.
    pub fn max_binding_bytes(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// Fails with [`GpuError::TooLarge`] when `bytes` exceed one storage binding.
    pub fn check_fits(&self, what: &str, bytes: u64) -> Result<(), GpuError> {
        let limit = self.max_binding_bytes();
        if bytes > limit {
            return Err(GpuError::TooLarge {
                what: what.to_string(),
                bytes,
                limit,
                adapter: self.info.name.clone(),
            });
        }
        Ok(())
    }

    /// Runs `f` (which records and submits GPU work) under out-of-memory, validation and
    /// internal error scopes, and turns whatever they caught, a device loss, or an error that
    /// escaped to the uncaptured handler, into a [`GpuError`] naming `during`.
    ///
    /// A device that is already lost or destroyed fails first, without running `f`: wgpu
    /// reports the loss only from a poll, and until then some of its calls panic on the dead
    /// device (`create_buffer_init` cannot map the buffer it created), so this polls, without
    /// waiting, and checks before touching the device.
    pub fn scoped<T>(&self, during: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        // The poll's own outcome is irrelevant here; a loss it finds runs the lost callback.
        let _ = self.device.poll(wgpu::PollType::Poll);
        self.check_health(during)?;
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let val = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let internal = self.device.push_error_scope(wgpu::ErrorFilter::Internal);
        let out = f();
        let e_internal = pollster::block_on(internal.pop());
        let e_val = pollster::block_on(val.pop());
        let e_oom = pollster::block_on(oom.pop());
        self.check_health(during)?;
        if let Some(e) = e_oom.or(e_val).or(e_internal) {
            return Err(GpuError::from_wgpu(during, e));
        }
        Ok(out)
    }

    /// Fails if the device was lost or an error escaped the error scopes.
    pub fn check_health(&self, during: &str) -> Result<(), GpuError> {
        if let Some(msg) = self.lost.lock().ok().and_then(|l| l.clone()) {
            return Err(GpuError::DeviceLost {
                during: during.to_string(),
                detail: msg,
            });
        }
        if let Some(e) = self.uncaptured.lock().ok().and_then(|mut u| u.take()) {
            return Err(GpuError::from_wgpu(during, e));
        }
        Ok(())
    }

    /// Blocks until all submitted work is done.
    pub fn wait(&self, during: &str) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .map_err(|e| GpuError::Poll {
                during: during.to_string(),
                detail: e.to_string(),
            })?;
        self.check_health(during)
    }

    /// A storage buffer initialised from `data` (at least 4 bytes: empty slices get one zero
    /// word so that bindings stay valid). Checks the binding limit first.
    pub fn storage_buffer<T: bytemuck::Pod>(
        &self,
        label: &str,
        data: &[T],
        extra_usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        self.check_fits(label, bytes.len() as u64)?;
        let zero = [0u8; 16];
        let contents = if bytes.is_empty() { &zero[..] } else { bytes };
        self.scoped(label, || {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage: wgpu::BufferUsages::STORAGE | extra_usage,
                })
        })
    }

    /// An uninitialised (zeroed) storage buffer of `bytes` bytes (rounded up to 16).
    pub fn storage_buffer_zeroed(
        &self,
        label: &str,
        bytes: u64,
        extra_usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        self.check_fits(label, bytes)?;
        let size = bytes.max(16).div_ceil(16) * 16;
        self.scoped(label, || {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | extra_usage,
                mapped_at_creation: false,
            })
        })
    }

    /// Copies the first `count` elements of `buffer` (which needs `COPY_SRC`) back to the CPU.
    pub fn read_buffer<T: bytemuck::Pod>(
        &self,
        buffer: &wgpu::Buffer,
        count: usize,
    ) -> Result<Vec<T>, GpuError> {
        let bytes = (count * std::mem::size_of::<T>()) as u64;
        if bytes == 0 {
            return Ok(Vec::new());
        }
        let padded = bytes.div_ceil(wgpu::COPY_BUFFER_ALIGNMENT) * wgpu::COPY_BUFFER_ALIGNMENT;
        let label = "read-back".to_string();
        let staging = self.scoped(&label, || {
            let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raylume read-back"),
                size: padded,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut enc = self.device.create_command_encoder(&Default::default());
            enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, padded);
            self.queue.submit([enc.finish()]);
            staging
        })?;
        let (tx, rx) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        self.wait(&label)?;
        match rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                return Err(GpuError::Map {
                    during: label,
                    detail: e.to_string(),
                });
            }
            Err(_) => {
                return Err(GpuError::Map {
                    during: label,
                    detail: "the map callback never ran".into(),
                });
            }
        }
        let view = staging.get_mapped_range(..).map_err(|e| GpuError::Map {
            during: label.clone(),
            detail: e.to_string(),
        })?;
        let out = bytemuck::cast_slice::<u8, T>(&view[..bytes as usize]).to_vec();
        drop(view);
        staging.unmap();
        Ok(out)
    }
}

/// The backend sets to try in order: `WGPU_BACKEND` if set, else the primary ones, then GL.
fn backend_order() -> Vec<wgpu::Backends> {
    match wgpu::Backends::from_env() {
        Some(b) => vec![b],
        None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::GL],
    }
}
