//! Runs an exported shader's test entry point on a Vulkan adapter (feature `gpu`), to compare its
//! values with the core's. Without a GPU, Mesa's lavapipe (package `mesa-vulkan-drivers`) is one: the
//! SPIR-V that naga writes is compiled by Mesa to CPU code, so the shader's own arithmetic is checked.

use wgpu::util::DeviceExt;

use crate::entry::{TEST_ENTRY, TEST_IN_STRIDE_BASE, TEST_OUT_STRIDE};
use crate::{Shader, Storage};

/// A Vulkan device to run shaders on.
pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The adapter, in words (name, driver, type).
    pub adapter: String,
}

impl Gpu {
    /// The first Vulkan adapter, or why there is none (the caller prints it as the reason of a skip).
    pub fn new() -> Result<Gpu, String> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::VULKAN;
        let instance = wgpu::Instance::new(desc);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
            .map_err(|e| format!("no Vulkan adapter ({e}); install a driver, e.g. Mesa lavapipe (mesa-vulkan-drivers)"))?;
        let info = adapter.get_info();
        let name = format!("{} ({}, {}, {:?})", info.name, info.driver, info.driver_info, info.device_type);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("nbrdf-shader test"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| format!("the adapter {name} gave no device: {e}"))?;
        Ok(Gpu { device, queue, adapter: name })
    }

    /// Runs the test entry point of `shader` on queries laid out as `crate::entry` documents
    /// (`TEST_IN_STRIDE_BASE + position_len` values each) and returns `TEST_OUT_STRIDE` values per
    /// query.
    pub fn run(&self, shader: &Shader, queries: &[f32]) -> Result<Vec<f32>, String> {
        let stride = TEST_IN_STRIDE_BASE + shader.position_len;
        if queries.is_empty() || !queries.len().is_multiple_of(stride) {
            return Err(format!("{} query values are not whole queries of {stride}", queries.len()));
        }
        let n = queries.len() / stride;
        let d = &self.device;
        let scope = d.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("nbrdf"),
            source: wgpu::ShaderSource::Wgsl(shader.wgsl.as_str().into()),
        });
        let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("nbrdf"),
            layout: None,
            module: &module,
            entry_point: Some(TEST_ENTRY),
            compilation_options: Default::default(),
            cache: None,
        });
        let storage = |contents: &[f32], usage| {
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents: &contents.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>(),
                usage,
            })
        };
        let input = storage(queries, wgpu::BufferUsages::STORAGE);
        let out_len = (n * TEST_OUT_STRIDE * 4) as u64;
        let output = d.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: out_len,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: out_len,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let weights = match shader.storage {
            Storage::Buffer { group, binding } => Some((group, binding, storage(&shader.weights, wgpu::BufferUsages::STORAGE))),
            Storage::Inline => None,
        };
        let mut groups = vec![(0u32, vec![(0u32, &input), (1, &output)])];
        if let Some((group, binding, buf)) = &weights {
            match groups.iter_mut().find(|(g, _)| g == group) {
                Some((_, entries)) => entries.push((*binding, buf)),
                None => groups.push((*group, vec![(*binding, buf)])),
            }
        }
        let bind_groups: Vec<(u32, wgpu::BindGroup)> = groups
            .iter()
            .map(|(g, entries)| {
                let entries: Vec<wgpu::BindGroupEntry> =
                    entries.iter().map(|(b, buf)| wgpu::BindGroupEntry { binding: *b, resource: buf.as_entire_binding() }).collect();
                let layout = pipeline.get_bind_group_layout(*g);
                (*g, d.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout: &layout, entries: &entries }))
            })
            .collect();
        let mut encoder = d.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
            pass.set_pipeline(&pipeline);
            for (g, bg) in &bind_groups {
                pass.set_bind_group(*g, bg, &[]);
            }
            pass.dispatch_workgroups(n.div_ceil(64) as u32, 1, 1);
        }
        encoder.copy_buffer_to_buffer(&output, 0, &readback, 0, out_len);
        self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(format!("wgpu rejected the shader or its bindings: {e}"));
        }
        let slice = readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        d.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| format!("waiting for the adapter: {e}"))?;
        let data = slice.get_mapped_range().map_err(|e| format!("reading the results back: {e}"))?;
        let values = data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        drop(data);
        readback.unmap();
        Ok(values)
    }
}
