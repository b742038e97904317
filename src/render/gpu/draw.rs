//! What the draw pass writes and reads besides the source: the output target (the storage
//! buffer it writes the frame into, and the ring of readback buffers that frame is copied to)
//! and the buffer holding the block map of the frame's rectangles.

use super::blocks::BlockMap;
use super::ring::{MapSlot, RING};
use crate::frame::PlaneLayout;
use crate::layout::Rect;

/// What depends on the output layout: the storage buffer the draw pass writes, readback ring.
pub(super) struct Target {
    pub layout: PlaneLayout,
    pub buffer: wgpu::Buffer,
    pub readbacks: Vec<MapSlot>,
}

impl Target {
    pub fn new(device: &wgpu::Device, layout: PlaneLayout) -> Target {
        let size = layout.size as u64;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("output frame"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readbacks = (0..RING)
            .map(|i| {
                MapSlot::new(
                    device,
                    &format!("readback {i}"),
                    size,
                    wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                )
            })
            .collect();
        Target {
            layout,
            buffer,
            readbacks,
        }
    }

    /// Copies the frame drawn into readback buffer `slot`.
    pub fn encode_readback(&self, encoder: &mut wgpu::CommandEncoder, slot: usize) {
        encoder.copy_buffer_to_buffer(&self.buffer, 0, &self.readbacks[slot].buffer, 0, None);
    }
}

/// The block map of the last frame's rectangles and the buffer holding it.
pub(super) struct BlockBuffer {
    pub map: BlockMap,
    pub buffer: wgpu::Buffer,
}

impl BlockBuffer {
    /// Makes `blocks` hold the map of a `width` × `height` frame of views `rects`, rewriting
    /// its buffer when they change. True when the buffer is new (too small before), so the
    /// bindings that name it must be made again.
    pub fn follow(
        blocks: &mut Option<BlockBuffer>,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (width, height): (u32, u32),
        rects: &[Rect],
    ) -> bool {
        if blocks
            .as_ref()
            .is_some_and(|b| b.map.is_for(width, height, rects))
        {
            return false;
        }
        let map = BlockMap::new(width, height, rects);
        let words = map.words();
        let size = (words.len() * 4) as u64;
        let (buffer, new) = match blocks.take() {
            Some(b) if b.buffer.size() >= size => (b.buffer, false),
            _ => {
                let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("block map"),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                (buffer, true)
            }
        };
        queue.write_buffer(&buffer, 0, bytemuck::cast_slice(&words));
        *blocks = Some(BlockBuffer { map, buffer });
        new
    }

    /// Blocks the draw pass's per-pixel dispatch draws.
    pub fn mixed(&self) -> u32 {
        self.map.mixed.len() as u32
    }
}
