//! Rendering with each stage submitted and waited for on its own, to time the stages
//! (`digiview bench`); slower than [`Renderer::push`], which overlaps them.

use super::{RING, RenderedFrame, Renderer};
use crate::frame::PlaneLayout;
use crate::plan::FramePlan;
use crate::render::gpu::GpuError;
use std::time::{Duration, Instant};

/// Where one frame's time went, each stage waited for on its own (see
/// [`Renderer::render_staged`]).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    /// A lens pair's seam blended, copy into the upload buffer, transfer, format conversion
    /// and mip chain.
    pub upload: Duration,
    /// The draw pass.
    pub render: Duration,
    /// Copy to the readback buffer, map, and copy out.
    pub readback: Duration,
}

impl Renderer {
    /// Renders one frame with each stage submitted and waited for on its own, to time the
    /// stages (slower than [`Renderer::push`], which overlaps them).
    pub fn render_staged(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
    ) -> Result<(RenderedFrame, StageTimes), GpuError> {
        while self.flush()?.is_some() {}
        let t0 = Instant::now();
        // The upload's time includes a lens pair's seam, blended on the host first.
        self.with_stitched(data, input, plan, |r, data| r.stages(data, input, plan, t0))
    }

    /// [`Renderer::render_staged`] once the frame is as the renderer draws it.
    fn stages(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
        t0: Instant,
    ) -> Result<(RenderedFrame, StageTimes), GpuError> {
        self.prepare(data, input, plan)?;
        let id = self.next_id;
        self.next_id += 1;
        let slot = (id % RING as u64) as usize;
        let device = self.gpu.device.clone();
        let wait = |index| {
            device
                .poll(wgpu::PollType::Wait {
                    submission_index: Some(index),
                    timeout: None,
                })
                .map_err(|e| GpuError::Failed(e.to_string()))
        };
        self.fill_upload(slot, data)?;
        let mut encoder = self.encoder();
        self.encode_upload(&mut encoder, slot);
        wait(self.submit(encoder))?;
        self.input.as_ref().unwrap().uploads[slot].request(wgpu::MapMode::Write);
        let t1 = Instant::now();
        let mut encoder = self.encoder();
        self.encode_draw(&mut encoder);
        wait(self.submit(encoder))?;
        let t2 = Instant::now();
        let mut encoder = self.encoder();
        let target = self.main.target.as_ref().unwrap();
        target.encode_readback(&mut encoder, slot);
        self.submit(encoder);
        let readback = &target.readbacks[slot];
        readback.request(wgpu::MapMode::Read);
        readback.wait(&device)?;
        let data = readback.read_out(target.layout.size as usize)?;
        let t3 = Instant::now();
        let frame = RenderedFrame {
            id,
            layout: target.layout,
            data,
            latency: t3 - t0,
        };
        let times = StageTimes {
            upload: t1 - t0,
            render: t2 - t1,
            readback: t3 - t2,
        };
        Ok((frame, times))
    }
}
