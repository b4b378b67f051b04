//! The device the GPU tracer runs on: a wgpu instance over the primary backends, its adapter,
//! device and queue, errors collected instead of panicking, and blocking read-backs.

use std::sync::{Arc, Mutex};

use bytemuck::Pod;

/// An open GPU device.
pub struct GpuContext {
    /// The adapter (physical device).
    pub adapter: wgpu::Adapter,
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    errors: Arc<Mutex<Vec<String>>>,
}

impl GpuContext {
    /// Opens the best adapter of the platform's primary backends (Vulkan, Metal, DX12):
    /// a hardware GPU if there is one, else a software one such as lavapipe, with the
    /// adapter's own limits. Errors say what is missing.
    pub fn new() -> Result<Self, String> {
        let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle();
        descriptor.backends = wgpu::Backends::PRIMARY;
        let instance = wgpu::Instance::new(descriptor);
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        };
        let adapter = pollster::block_on(instance.request_adapter(&options)).map_err(|e| {
            format!(
                "no GPU adapter ({e}); install a Vulkan driver, e.g. Mesa's lavapipe with scripts/provision-vulkan.sh"
            )
        })?;
        let limits = adapter.limits();
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("lodestar"),
            required_features: wgpu::Features::empty(),
            required_limits: limits,
            ..Default::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&descriptor)).map_err(|e| format!("cannot open the GPU: {e}"))?;
        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |error: wgpu::Error| {
            if let Ok(mut errors) = sink.lock() {
                errors.push(error.to_string());
            }
        }));
        Ok(Self { adapter, device, queue, errors })
    }

    /// The adapter's name and device type, e.g. "llvmpipe (LLVM 15.0.6, 256 bits), Cpu".
    pub fn describe(&self) -> String {
        let info = self.adapter.get_info();
        format!("{}, {:?}", info.name, info.device_type)
    }

    /// Whether the adapter is a software rasteriser (lavapipe).
    pub fn is_software(&self) -> bool {
        self.adapter.get_info().device_type == wgpu::DeviceType::Cpu
    }

    /// The errors the device reported since the last call, as one error.
    pub fn check_errors(&self) -> Result<(), String> {
        let mut errors = self.errors.lock().map_err(|_| "GPU error log poisoned".to_string())?;
        if errors.is_empty() {
            return Ok(());
        }
        let message = errors.join("; ");
        errors.clear();
        Err(format!("GPU error: {message}"))
    }

    /// Copies a storage buffer to the host, as words.
    pub fn copy_to_host(&self, buffer: &wgpu::Buffer) -> Result<Vec<u32>, String> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("guide readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
        self.queue.submit([encoder.finish()]);
        self.read(&staging)
    }

    /// Waits for the queue, then copies a mappable buffer's contents out.
    pub fn read<T: Pod>(&self, buffer: &wgpu::Buffer) -> Result<Vec<T>, String> {
        let (sender, receiver) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |result| {
            let _ = sender.send(result);
        });
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| format!("GPU wait failed: {e}"))?;
        receiver
            .recv()
            .map_err(|_| "GPU read-back never completed".to_string())?
            .map_err(|e| format!("GPU read-back failed: {e}"))?;
        let values = {
            let view = buffer.get_mapped_range(..).map_err(|e| format!("GPU read-back failed: {e}"))?;
            bytemuck::cast_slice::<u8, T>(&view).to_vec()
        };
        buffer.unmap();
        self.check_errors()?;
        Ok(values)
    }
}
