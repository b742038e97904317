//! The renderer's rings of host-mapped buffers (uploads and readbacks), one per frame in
//! flight, so frame N uploads and draws while frame N-1 is read back. Each buffer carries its
//! mapping state, which wgpu's map callback sets; readback in the documented order (copy,
//! `map_async`, poll, read, unmap).

use super::GpuError;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

/// Frames in flight: frame N renders while frame N-1 is read back.
pub const RING: usize = 2;

const PENDING: u8 = 0;
const MAPPED: u8 = 1;
const FAILED: u8 = 2;

/// A buffer of a ring with its mapping state, set by wgpu's map callback.
#[derive(Clone)]
pub(super) struct MapSlot {
    pub buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
}

impl MapSlot {
    /// A buffer of `usage`; one the host writes (MAP_WRITE) starts mapped.
    pub fn new(device: &wgpu::Device, label: &str, size: u64, usage: wgpu::BufferUsages) -> Self {
        let write = usage.contains(wgpu::BufferUsages::MAP_WRITE);
        MapSlot {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: write,
            }),
            state: Arc::new(AtomicU8::new(if write { MAPPED } else { PENDING })),
        }
    }

    /// Asks for the buffer to be mapped once the GPU is done with it.
    pub fn request(&self, mode: wgpu::MapMode) {
        self.state.store(PENDING, Ordering::Release);
        let state = self.state.clone();
        self.buffer.map_async(mode, .., move |r| {
            state.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
        });
    }

    /// Waits until the buffer is mapped.
    pub fn wait(&self, device: &wgpu::Device) -> Result<(), GpuError> {
        while self.state.load(Ordering::Acquire) == PENDING {
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Failed(e.to_string()))?;
        }
        match self.state.load(Ordering::Acquire) {
            MAPPED => Ok(()),
            _ => Err(GpuError::Failed("mapping a ring buffer failed".into())),
        }
    }

    /// Copies the mapped buffer's first `len` bytes out and unmaps it.
    pub fn read_out(&self, len: usize) -> Result<Vec<u8>, GpuError> {
        let data = {
            let view = self
                .buffer
                .get_mapped_range(..)
                .map_err(|e| GpuError::Failed(e.to_string()))?;
            view[..len].to_vec()
        };
        self.buffer.unmap();
        Ok(data)
    }
}
