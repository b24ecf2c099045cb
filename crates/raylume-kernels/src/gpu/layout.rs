//! Bind-group layout entries and scene uploads.

use raylume_gpu::{GpuContext, wgpu};

use crate::KernelError;

pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

pub(crate) fn uniform_entry(binding: u32, dynamic: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A storage buffer holding `data`, or one default element when `data` is empty (a binding
/// must hold at least one element). A buffer over the adapter's limit is a
/// [`KernelError::SceneTooLarge`] naming `label`.
pub(crate) fn upload<T: bytemuck::Pod + Default>(
    ctx: &GpuContext,
    label: &str,
    data: &[T],
) -> Result<wgpu::Buffer, KernelError> {
    let one = [T::default()];
    let data = if data.is_empty() { &one[..] } else { data };
    ctx.storage_buffer(label, data, wgpu::BufferUsages::empty())
        .map_err(KernelError::from_upload)
}

/// [`upload`] with room for `room` more elements after `data` (zeroed), which a later
/// `write_buffer` fills (the buffer is a copy destination then).
pub(crate) fn upload_with_room<T: bytemuck::Pod + Default>(
    ctx: &GpuContext,
    label: &str,
    data: &[T],
    room: usize,
) -> Result<wgpu::Buffer, KernelError> {
    if room == 0 {
        return upload(ctx, label, data);
    }
    let bytes = ((data.len() + room) * std::mem::size_of::<T>()) as u64;
    let buffer = ctx
        .storage_buffer_zeroed(label, bytes, wgpu::BufferUsages::COPY_DST)
        .map_err(KernelError::from_upload)?;
    if !data.is_empty() {
        ctx.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(data));
    }
    Ok(buffer)
}

/// The layouts of group 0 (the scene: uniforms, then BVH nodes, primitives, materials,
/// primitive materials, triangle shading, texture headers, texels, lights, plastic tables), group 1 (the work
/// buffers, see `bindings.wgsl`; binding 8 at a dynamic offset), group 2 of
/// `prepare_propagate` (the dispatch size it writes) and group 2 of `permute_rays` (the state
/// buffer it fills).
pub(crate) fn bind_group_layouts(device: &wgpu::Device) -> [wgpu::BindGroupLayout; 4] {
    let scene = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("raylume scene"),
        entries: &[
            uniform_entry(0, false),
            storage_entry(1, true),
            storage_entry(2, true),
            storage_entry(3, true),
            storage_entry(4, true),
            storage_entry(5, true),
            storage_entry(6, true),
            storage_entry(7, true),
            storage_entry(8, true),
            storage_entry(9, true),
        ],
    });
    let work = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("raylume work"),
        entries: &[
            storage_entry(0, false),
            storage_entry(1, false),
            storage_entry(2, false),
            storage_entry(3, false),
            storage_entry(4, false),
            storage_entry(5, false),
            storage_entry(6, false),
            storage_entry(7, false),
            storage_entry(9, false),
            storage_entry(10, false),
            uniform_entry(8, true),
        ],
    });
    let args = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("raylume propagate dispatch size"),
        entries: &[storage_entry(0, false)],
    });
    let permute = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("raylume permuted ray states"),
        entries: &[storage_entry(1, false)],
    });
    [scene, work, args, permute]
}
