//! What the driver makes of the tracer's compute pipelines: registers per thread, registers
//! spilled (NVIDIA reports them as `Shared Memory Size`: the tracer declares 8 bytes of
//! workgroup memory at most), local memory (the traversal stack) and code size, per entry point,
//! estimator and scene, as the Vulkan driver reports them through
//! `VK_KHR_pipeline_executable_properties` (issue 13: what register use costs, how far each
//! feature's code moves occupancy).
//!
//! ```text
//! cargo run --release --example shader_stats -- scenes/living-room/scene.json
//!     [--estimator plain,nee] [--schedule persistent,megakernel,wavefront]
//!     [--bvh wide] [--sampler sobol] [--next-event-stage] [--walk-stage]
//!     [--each-extra-feature] [--json OUT]
//! ```
//!
//! wgpu does not ask the driver for statistics, so this example compiles the pipelines
//! itself with `ash` (the Vulkan bindings wgpu is built on): the scene's composed WGSL and
//! override constants as `TracerPipelines` makes them, translated to SPIR-V by naga with the
//! options wgpu's Vulkan backend uses for the tracer (no bounds checks, no loop bounding:
//! `GpuContext::shader_module`), each entry point compiled with `CAPTURE_STATISTICS`. The
//! statistics' names and meanings are the driver's (NVIDIA names e.g. "Register Count");
//! every one it gives is printed. `--each-extra-feature` adds a row per feature the scene
//! lacks, compiled in beside the scene's own (what `bench --extra-feature` times).
//!
//! A driver without the extension (Debian 12's lavapipe has none) gets a clear error, not
//! a table.

use std::collections::BTreeMap;
use std::ffi::{CStr, CString};
use std::path::PathBuf;

#[path = "support/scene_name.rs"]
mod support;
use support::scene_name;

use ash::vk;
use clap::Parser;
use raylume::{BvhLayout, Estimator, Feature, Sampler, Scene, Schedule};
use raylume_gpu::wgpu::naga;
use raylume_kernels::gpu::{
    PathVariant, Specialisation, TracerPipelines, compose, entry_constants,
    tracer_source_uncomposed, walk_stage_source,
};

#[derive(Parser, Debug)]
#[command(
    name = "shader_stats",
    about = "Registers and memory of the tracer's pipelines"
)]
struct Args {
    /// Scene files.
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Comma-separated estimators (plain, nee).
    #[arg(long, default_value = "plain,nee", value_delimiter = ',')]
    estimator: Vec<Estimator>,
    /// Comma-separated schedules whose entry points are compiled.
    #[arg(
        long,
        default_value = "persistent,megakernel,wavefront",
        value_delimiter = ','
    )]
    schedule: Vec<Schedule>,
    /// BVH layout whose traversal the module holds.
    #[arg(long, default_value = "wide")]
    bvh: BvhLayout,
    /// Sampler the path pipelines are compiled for.
    #[arg(long, default_value = "sobol")]
    sampler: Sampler,
    /// Also the wavefront with its `next_event` stage (NEE only).
    #[arg(long)]
    next_event_stage: bool,
    /// Also the wavefront with its walk stage (`trace_hits`, and `propagate` compiled to
    /// shade the hits it leaves; wide BVH only), and with NEE its shadow stage
    /// (`trace_shadows`, and `propagate` compiled to queue the shadow rays): the module holds
    /// the stages as `TracerPipelines` builds it on an adapter with subgroups.
    #[arg(long)]
    walk_stage: bool,
    /// A row per feature the scene lacks, compiled in beside the scene's.
    #[arg(long)]
    each_extra_feature: bool,
    /// Write the rows as JSON lines here too.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Compile this tracer source (every feature's code, as `--write-source` writes it)
    /// instead of the built-in one, composed for each scene: a variant's registers without
    /// a rebuild.
    #[arg(long)]
    source: Option<PathBuf>,
    /// Write the built-in tracer source (for `--bvh`, every feature's code inside its
    /// `//#if` markers) here and exit.
    #[arg(long)]
    write_source: Option<PathBuf>,
}

/// One compiled pipeline's statistics, by the driver's names, as text.
struct Row {
    scene: String,
    features: String,
    entry: &'static str,
    estimator: &'static str,
    stats: BTreeMap<String, String>,
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("shader_stats: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), String> {
    if args.walk_stage && args.bvh != BvhLayout::Wide {
        return Err("--walk-stage needs --bvh wide (the stage walks the wide tree)".into());
    }
    let mut full = tracer_source_uncomposed(65535, args.bvh);
    if args.walk_stage {
        full += &walk_stage_source();
    }
    if let Some(out) = &args.write_source {
        return std::fs::write(out, full).map_err(|e| format!("{}: {e}", out.display()));
    }
    let full = match &args.source {
        Some(p) => std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?,
        None => full,
    };
    let vk = Vulkan::new()?;
    println!("device: {} (driver {})", vk.device_name, vk.driver);
    println!(
        "| scene | features | entry point | estimator | registers | the driver's other statistics |"
    );
    println!("|---|---|---|---|---:|---|");
    let mut rows = Vec::new();
    for path in &args.scenes {
        let scene = Scene::load(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let name = scene_name(path);
        let own = Specialisation::default().features(scene.features());
        let mut sets = vec![(String::new(), own)];
        if args.each_extra_feature {
            for f in Feature::ALL {
                if !own.contains(f) {
                    sets.push((format!("+{}", f.name()), own.with(f)));
                }
            }
        }
        for (extra, features) in sets {
            // What `tracer_source_for(65535, args.bvh, features)` returns for the built-in
            // source.
            let source = compose(&full, features);
            let module = naga::front::wgsl::parse_str(&source)
                .map_err(|e| format!("{name}: {}", e.emit_to_string(&source)))?;
            let info = naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::all(),
            )
            .validate(&module)
            .map_err(|e| format!("{name}: {}", e.emit_to_string(&source)))?;
            for &estimator in &args.estimator {
                for (entry, variant) in entries(&args, estimator) {
                    let constants: naga::back::PipelineConstants =
                        entry_constants(features, entry, variant, false)
                            .into_iter()
                            .map(|(k, v)| (k.to_string(), v))
                            .collect();
                    let stats = vk.statistics(&module, &info, entry, &constants)?;
                    let estimator_name = match (estimator, variant.next_event_stage) {
                        _ if entry == "trace_hits" || entry == "trace_shadows" => "any",
                        (Estimator::Nee, false) if variant.defers_shadow_rays() => {
                            "nee+walk+shadow"
                        }
                        (Estimator::Plain, _) if variant.walk_stage => "plain+walk",
                        (Estimator::Plain, _) => "plain",
                        (Estimator::Nee, false) if variant.walk_stage => "nee+walk",
                        (Estimator::Nee, false) => "nee",
                        (Estimator::Nee, true) if variant.walk_stage => "nee+stage+walk",
                        (Estimator::Nee, true) => "nee+stage",
                    };
                    let row = Row {
                        scene: name.clone(),
                        features: if extra.is_empty() {
                            own.names().join(",")
                        } else {
                            extra.clone()
                        },
                        entry,
                        estimator: estimator_name,
                        stats,
                    };
                    print_row(&row);
                    rows.push(row);
                }
            }
        }
    }
    if let Some(out) = &args.json {
        let lines: Vec<String> = rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "scene": r.scene,
                    "features": r.features,
                    "entry": r.entry,
                    "estimator": r.estimator,
                    "stats": r.stats,
                })
                .to_string()
            })
            .collect();
        std::fs::write(out, lines.join("\n") + "\n")
            .map_err(|e| format!("{}: {e}", out.display()))?;
    }
    Ok(())
}

/// The path tracing entry points of the asked schedules for `estimator`, each with the
/// variant its pipeline is compiled for (`TracerPipelines`' choice: the `next_event` stage
/// matters to `propagate` and `next_event` only, the walk stage to `propagate` only; the
/// stage's own `trace_hits` traces no path and is compiled once, for any variant).
fn entries(args: &Args, estimator: Estimator) -> Vec<(&'static str, PathVariant)> {
    let base = PathVariant::of(estimator, args.sampler);
    let mut out: Vec<(&'static str, PathVariant)> = Vec::new();
    let mut push = |entry: &'static str, v: PathVariant| {
        if !out.contains(&(entry, v)) {
            out.push((entry, v));
        }
    };
    for &schedule in &args.schedule {
        let mut variants = vec![base];
        if schedule == Schedule::Wavefront && args.next_event_stage && estimator == Estimator::Nee {
            variants.push(base.with_next_event_stage(true));
        }
        if schedule == Schedule::Wavefront && args.walk_stage {
            let walked: Vec<PathVariant> =
                variants.iter().map(|v| v.with_walk_stage(true)).collect();
            variants.extend(walked);
            if estimator == Estimator::Nee {
                // And the shadow stage after the walk stage's `propagate`.
                variants.push(base.with_walk_stage(true).with_shadow_stage(true));
            }
        }
        for v in variants {
            for &entry in TracerPipelines::entries(schedule, v) {
                match entry {
                    "trace_paths" | "trace_paths_persistent" => push(entry, base),
                    "propagate" => push(entry, v),
                    "next_event" => push(entry, v.with_walk_stage(false)),
                    "trace_hits" | "trace_shadows" => push(entry, PathVariant::ANY),
                    _ => {}
                }
            }
        }
    }
    out
}

fn print_row(r: &Row) {
    let pick = |keys: &[&str]| {
        keys.iter()
            .find_map(|k| r.stats.get(*k).cloned())
            .unwrap_or_else(|| "-".into())
    };
    let rest: Vec<String> = r
        .stats
        .iter()
        .filter(|(k, _)| !k.contains("Register"))
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    println!(
        "| {} | {} | {} | {} | {} | {} |",
        r.scene,
        r.features,
        r.entry,
        r.estimator,
        pick(&["Register Count", "Registers"]),
        rest.join("; ")
    );
}

/// An instance and device of the first GPU with `VK_KHR_pipeline_executable_properties`
/// (a discrete one if there is one), the extension enabled.
struct Vulkan {
    _entry: ash::Entry,
    instance: ash::Instance,
    device: ash::Device,
    exec: ash::khr::pipeline_executable_properties::Device,
    device_name: String,
    driver: String,
}

impl Vulkan {
    fn new() -> Result<Self, String> {
        // SAFETY: loading the system's Vulkan loader, as wgpu does.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| format!("no Vulkan loader: {e}"))?;
        let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
        let instance = unsafe {
            entry.create_instance(
                &vk::InstanceCreateInfo::default().application_info(&app),
                None,
            )
        }
        .map_err(|e| format!("vkCreateInstance: {e}"))?;
        let ext = ash::khr::pipeline_executable_properties::NAME;
        let physical = unsafe { instance.enumerate_physical_devices() }
            .map_err(|e| format!("vkEnumeratePhysicalDevices: {e}"))?;
        let has_ext = |pd: vk::PhysicalDevice| {
            unsafe { instance.enumerate_device_extension_properties(pd) }
                .unwrap_or_default()
                .iter()
                .any(|p| p.extension_name_as_c_str() == Ok(ext))
        };
        let props = |pd| unsafe { instance.get_physical_device_properties(pd) };
        let mut candidates: Vec<_> = physical.into_iter().filter(|&pd| has_ext(pd)).collect();
        candidates.sort_by_key(|&pd| props(pd).device_type != vk::PhysicalDeviceType::DISCRETE_GPU);
        let Some(&pd) = candidates.first() else {
            return Err(format!(
                "no Vulkan device offers {} (the driver must report its pipelines' statistics)",
                ext.to_string_lossy()
            ));
        };
        let p = props(pd);
        let device_name = p
            .device_name_as_c_str()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let v = p.driver_version;
        let driver = if p.vendor_id == 0x10de {
            // NVIDIA packs its version as 10.8.8.6 bits (580.159.04).
            format!("{}.{}.{:02}", v >> 22, (v >> 14) & 0xff, (v >> 6) & 0xff)
        } else {
            format!(
                "{}.{}.{}",
                vk::api_version_major(v),
                vk::api_version_minor(v),
                vk::api_version_patch(v)
            )
        };
        // Every core feature the device has (whatever the SPIR-V asks for; robust buffer
        // access among them, as wgpu enables it), the extension's, and, as wgpu's Vulkan
        // backend, VK_EXT_robustness2 where the device has it (its robust buffer access
        // changes the code the driver makes for every buffer access).
        let robustness2 = ash::ext::robustness2::NAME;
        let has_robustness2 = unsafe { instance.enumerate_device_extension_properties(pd) }
            .unwrap_or_default()
            .iter()
            .any(|p| p.extension_name_as_c_str() == Ok(robustness2));
        let mut f11 = vk::PhysicalDeviceVulkan11Features::default();
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
        let mut r2 = vk::PhysicalDeviceRobustness2FeaturesEXT::default();
        let mut features = vk::PhysicalDeviceFeatures2::default()
            .push_next(&mut f11)
            .push_next(&mut f12)
            .push_next(&mut f13);
        if has_robustness2 {
            features = features.push_next(&mut r2);
        }
        unsafe { instance.get_physical_device_features2(pd, &mut features) };
        let core = features.features;
        let mut r2 = vk::PhysicalDeviceRobustness2FeaturesEXT::default()
            .robust_buffer_access2(r2.robust_buffer_access2 != 0)
            .robust_image_access2(r2.robust_image_access2 != 0);
        let mut exec_features =
            vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default()
                .pipeline_executable_info(true);
        let mut f11 = vk::PhysicalDeviceVulkan11Features {
            p_next: std::ptr::null_mut(),
            ..f11
        };
        let mut f12 = vk::PhysicalDeviceVulkan12Features {
            p_next: std::ptr::null_mut(),
            ..f12
        };
        let mut f13 = vk::PhysicalDeviceVulkan13Features {
            p_next: std::ptr::null_mut(),
            ..f13
        };
        let mut enabled = vk::PhysicalDeviceFeatures2::default()
            .features(core)
            .push_next(&mut f11)
            .push_next(&mut f12)
            .push_next(&mut f13)
            .push_next(&mut exec_features);
        if has_robustness2 {
            enabled = enabled.push_next(&mut r2);
        }
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(0)
            .queue_priorities(&priorities)];
        let mut extensions = vec![ext.as_ptr()];
        if has_robustness2 {
            extensions.push(robustness2.as_ptr());
        }
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&extensions)
            .push_next(&mut enabled);
        let device = unsafe { instance.create_device(pd, &info, None) }
            .map_err(|e| format!("vkCreateDevice: {e}"))?;
        let exec = ash::khr::pipeline_executable_properties::Device::new(&instance, &device);
        Ok(Self {
            _entry: entry,
            instance,
            device,
            exec,
            device_name,
            driver,
        })
    }

    /// Compiles `entry` of `module` with `constants` and returns the driver's statistics
    /// of its executables (one for a compute pipeline), prefixed by the executable's name
    /// when there are several.
    fn statistics(
        &self,
        module: &naga::Module,
        info: &naga::valid::ModuleInfo,
        entry: &str,
        constants: &naga::back::PipelineConstants,
    ) -> Result<BTreeMap<String, String>, String> {
        let stage = naga::ShaderStage::Compute;
        let (module, info) = naga::back::pipeline_constants::process_overrides(
            module,
            info,
            Some((stage, entry)),
            constants,
        )
        .map_err(|e| format!("{entry}: overrides: {e}"))?;
        let options = naga::back::spv::Options {
            lang_version: (1, 6),
            flags: naga::back::spv::WriterFlags::empty(),
            capabilities: None,
            bounds_check_policies: naga::proc::BoundsCheckPolicies {
                index: naga::proc::BoundsCheckPolicy::Unchecked,
                buffer: naga::proc::BoundsCheckPolicy::Unchecked,
                image_load: naga::proc::BoundsCheckPolicy::Unchecked,
                binding_array: naga::proc::BoundsCheckPolicy::Unchecked,
            },
            zero_initialize_workgroup_memory:
                naga::back::spv::ZeroInitializeWorkgroupMemoryMode::Native,
            force_loop_bounding: false,
            ..Default::default()
        };
        let pipeline_options = naga::back::spv::PipelineOptions {
            shader_stage: stage,
            entry_point: entry.to_string(),
        };
        let words = naga::back::spv::write_vec(&module, &info, &options, Some(&pipeline_options))
            .map_err(|e| format!("{entry}: SPIR-V: {e}"))?;
        let d = &self.device;
        // The descriptor sets the module binds: every buffer a storage or uniform buffer.
        let mut sets: BTreeMap<u32, Vec<vk::DescriptorSetLayoutBinding>> = BTreeMap::new();
        for (_, var) in module.global_variables.iter() {
            let Some(b) = &var.binding else { continue };
            let ty = match var.space {
                naga::AddressSpace::Uniform => vk::DescriptorType::UNIFORM_BUFFER,
                naga::AddressSpace::Storage { .. } => vk::DescriptorType::STORAGE_BUFFER,
                other => return Err(format!("{entry}: a binding in {other:?}: not handled")),
            };
            sets.entry(b.group).or_default().push(
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(ty)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE),
            );
        }
        let groups = sets.keys().next_back().map_or(0, |g| g + 1);
        let mut set_layouts = Vec::new();
        let result = (|| unsafe {
            for g in 0..groups {
                let bindings = sets.get(&g).cloned().unwrap_or_default();
                let l = d
                    .create_descriptor_set_layout(
                        &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                        None,
                    )
                    .map_err(|e| format!("{entry}: set layout: {e}"))?;
                set_layouts.push(l);
            }
            let layout = d
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts),
                    None,
                )
                .map_err(|e| format!("{entry}: pipeline layout: {e}"))?;
            let shader = d
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
                .map_err(|e| format!("{entry}: shader module: {e}"))?;
            let name = CString::new(entry).map_err(|e| e.to_string())?;
            let stage_info = vk::PipelineShaderStageCreateInfo::default()
                .flags(vk::PipelineShaderStageCreateFlags::ALLOW_VARYING_SUBGROUP_SIZE)
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(shader)
                .name(&name);
            let create = vk::ComputePipelineCreateInfo::default()
                .flags(vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR)
                .stage(stage_info)
                .layout(layout);
            let compiled = d.create_compute_pipelines(vk::PipelineCache::null(), &[create], None);
            d.destroy_shader_module(shader, None);
            let pipeline = match compiled {
                Ok(p) => p[0],
                Err((_, e)) => {
                    d.destroy_pipeline_layout(layout, None);
                    return Err(format!("{entry}: vkCreateComputePipelines: {e}"));
                }
            };
            let out = self.read_statistics(pipeline);
            d.destroy_pipeline(pipeline, None);
            d.destroy_pipeline_layout(layout, None);
            out.map_err(|e| format!("{entry}: {e}"))
        })();
        for l in set_layouts {
            unsafe { d.destroy_descriptor_set_layout(l, None) };
        }
        result
    }

    fn read_statistics(&self, pipeline: vk::Pipeline) -> Result<BTreeMap<String, String>, String> {
        let mut out = BTreeMap::new();
        let executables = unsafe {
            self.exec.get_pipeline_executable_properties(
                &vk::PipelineInfoKHR::default().pipeline(pipeline),
            )
        }
        .map_err(|e| format!("vkGetPipelineExecutablePropertiesKHR: {e}"))?;
        let several = executables.len() > 1;
        for (i, e) in executables.iter().enumerate() {
            let exe_name = e
                .name_as_c_str()
                .map(CStr::to_string_lossy)
                .unwrap_or_default();
            out.insert(
                if several {
                    format!("{exe_name}: subgroup")
                } else {
                    "subgroup".into()
                },
                e.subgroup_size.to_string(),
            );
            let stats = unsafe {
                self.exec.get_pipeline_executable_statistics(
                    &vk::PipelineExecutableInfoKHR::default()
                        .pipeline(pipeline)
                        .executable_index(i as u32),
                )
            }
            .map_err(|e| format!("vkGetPipelineExecutableStatisticsKHR: {e}"))?;
            for s in &stats {
                let name = s
                    .name_as_c_str()
                    .map(CStr::to_string_lossy)
                    .unwrap_or_default();
                // SAFETY: the union's member is the one `format` names.
                let value = unsafe {
                    match s.format {
                        vk::PipelineExecutableStatisticFormatKHR::BOOL32 => {
                            (s.value.b32 != 0).to_string()
                        }
                        vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64.to_string(),
                        // NVIDIA's "Local Memory Size" has bits above the low 32 set
                        // (0x10_0000_0100 for 256 bytes a thread): shown as the low word,
                        // with the raw value.
                        vk::PipelineExecutableStatisticFormatKHR::UINT64 => match s.value.u64 {
                            v if v > u64::from(u32::MAX) => format!("{} (raw {v:#x})", v as u32),
                            v => v.to_string(),
                        },
                        vk::PipelineExecutableStatisticFormatKHR::FLOAT64 => {
                            s.value.f64.to_string()
                        }
                        _ => "?".into(),
                    }
                };
                let key = if several {
                    format!("{exe_name}: {name}")
                } else {
                    name.into_owned()
                };
                out.insert(key, value);
            }
        }
        Ok(out)
    }
}

impl Drop for Vulkan {
    fn drop(&mut self) {
        unsafe {
            self.device.destroy_device(None);
            self.instance.destroy_instance(None);
        }
    }
}
