//! Which GPU renders: a real one when there is one (discrete, then integrated, then virtual),
//! Mesa's lavapipe software rasterizer otherwise. `DIGIVIEW_ADAPTER=<name part>` picks one
//! by name. The choice is logged at start-up; no adapter at all is an error that says what
//! to install.

use super::GpuError;
use wgpu::{Adapter, AdapterInfo, DeviceType};

/// An open device and its queue; cheap to clone.
#[derive(Clone, Debug)]
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: AdapterInfo,
    /// The device reads buffers the host maps as fast as its own (a software rasterizer or an
    /// integrated GPU) and may use them as storage: the renderer then reads uploaded frames
    /// where they were written, without copying them first.
    pub shared_memory: bool,
}

fn rank(t: DeviceType) -> u8 {
    match t {
        DeviceType::DiscreteGpu => 0,
        DeviceType::IntegratedGpu => 1,
        DeviceType::VirtualGpu => 2,
        DeviceType::Other => 3,
        DeviceType::Cpu => 4,
    }
}

fn describe(info: &AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, {} {})",
        info.name, info.backend, info.device_type, info.driver, info.driver_info
    )
}

impl Gpu {
    /// Opens the best adapter (or the one `DIGIVIEW_ADAPTER` names).
    pub fn new() -> Result<Gpu, GpuError> {
        Self::with_adapter(std::env::var("DIGIVIEW_ADAPTER").ok().as_deref())
    }

    /// Opens the best adapter, or the first whose name contains `wanted` (case-insensitive).
    pub fn with_adapter(wanted: Option<&str>) -> Result<Gpu, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let mut adapters: Vec<Adapter> =
            pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        if adapters.is_empty() {
            let icd = std::env::var("VK_ICD_FILENAMES")
                .map(|v| format!(" (VK_ICD_FILENAMES is set to {v:?}; unset it to search all)"))
                .unwrap_or_default();
            return Err(GpuError::NoAdapter(icd));
        }
        adapters.sort_by_key(|a| (rank(a.get_info().device_type), a.get_info().backend as u8));
        let adapter = match wanted {
            None => adapters.remove(0),
            Some(w) => {
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                let i = names
                    .iter()
                    .position(|n| n.to_lowercase().contains(&w.to_lowercase()))
                    .ok_or_else(|| GpuError::AdapterNotFound {
                        wanted: w.to_string(),
                        found: names.join(", "),
                    })?;
                adapters.remove(i)
            }
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let mappable = wgpu::Features::MAPPABLE_PRIMARY_BUFFERS;
        let shared_memory = matches!(
            info.device_type,
            DeviceType::Cpu | DeviceType::IntegratedGpu
        ) && adapter.features().contains(mappable);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("digiview"),
            required_features: if shared_memory {
                mappable
            } else {
                wgpu::Features::empty()
            },
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|source| GpuError::Device {
            adapter: describe(&info),
            source,
        })?;
        tracing::info!("GPU: {}", describe(&info));
        Ok(Gpu {
            device,
            queue,
            info,
            shared_memory,
        })
    }

    /// The adapter in one line: name, backend, type, driver.
    pub fn describe(&self) -> String {
        describe(&self.info)
    }

    /// Whether this is a software rasterizer (lavapipe) rather than a GPU.
    pub fn is_software(&self) -> bool {
        self.info.device_type == DeviceType::Cpu
    }
}
