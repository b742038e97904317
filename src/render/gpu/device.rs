//! The GPUs there are: a backend's adapters, best first (discrete, then integrated, then
//! virtual, Mesa's software rasterizers last: lavapipe for Vulkan, llvmpipe for GL), and one
//! opened. `DIGIVIEW_ADAPTER=<name part>` keeps those of that name. Which one renders is
//! `render::choose`'s: it checks each draws right. No adapter at all is an error that says
//! what to install.

use super::GpuError;
use crate::modes::GpuBackend;
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
    /// A test switch (`DIGIVIEW_FAULT=black-adapter`, `render::choose`): every frame read
    /// back is zeros, as a driver that draws nothing gives.
    pub(crate) draws_black: bool,
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

pub fn describe(info: &AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, {} {})",
        info.name, info.backend, info.device_type, info.driver, info.driver_info
    )
}

/// The adapters of `backend`, best first: a real GPU before a software rasterizer, and on
/// the same kind of device Vulkan (or the platform's own API) before GL. Where
/// `DIGIVIEW_ADAPTER` is set, only those whose name contains it (case-insensitive).
pub fn adapters(backend: GpuBackend) -> Result<Vec<Adapter>, GpuError> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let backends = match backend {
        GpuBackend::Auto => wgpu::Backends::PRIMARY | wgpu::Backends::GL,
        GpuBackend::Vulkan => wgpu::Backends::PRIMARY,
        GpuBackend::Gl => wgpu::Backends::GL,
    };
    let mut adapters: Vec<Adapter> = pollster::block_on(instance.enumerate_adapters(backends));
    if adapters.is_empty() {
        return Err(GpuError::NoAdapter(no_adapter_hint(backend)));
    }
    adapters.sort_by_key(|a| (rank(a.get_info().device_type), a.get_info().backend as u8));
    let Ok(wanted) = std::env::var("DIGIVIEW_ADAPTER") else {
        return Ok(adapters);
    };
    let found: Vec<String> = adapters.iter().map(|a| describe(&a.get_info())).collect();
    adapters.retain(|a| {
        let name = a.get_info().name.to_lowercase();
        name.contains(&wanted.to_lowercase())
    });
    if adapters.is_empty() {
        return Err(GpuError::AdapterNotFound {
            wanted,
            found: found.join(", "),
        });
    }
    Ok(adapters)
}

/// What to install when `backend` has no adapter.
fn no_adapter_hint(backend: GpuBackend) -> String {
    let vulkan = "for Vulkan, `apt-get install libvulkan1 mesa-vulkan-drivers` (Mesa's \
                  lavapipe software driver works everywhere) or your GPU vendor's driver";
    let gl = "for GL, `apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri` (Mesa's \
              llvmpipe works everywhere)";
    let icd = std::env::var("VK_ICD_FILENAMES")
        .map(|v| format!(" (VK_ICD_FILENAMES is set to {v:?}; unset it to search all)"))
        .unwrap_or_default();
    match backend {
        GpuBackend::Auto => format!("; on Debian or Ubuntu, as root: {vulkan}{icd}; or {gl}"),
        GpuBackend::Vulkan => format!(" with --backend vulkan; as root: {vulkan}{icd}"),
        GpuBackend::Gl => format!(" with --backend gl; as root: {gl}"),
    }
}

impl Gpu {
    /// Opens `adapter`'s device with all its limits (and, where the host's memory is the
    /// device's, buffers both map).
    pub fn open(adapter: &Adapter) -> Result<Gpu, GpuError> {
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
        Ok(Gpu {
            device,
            queue,
            info,
            shared_memory,
            draws_black: false,
        })
    }

    /// The adapter in one line: name, backend, type, driver.
    pub fn describe(&self) -> String {
        describe(&self.info)
    }

    /// The backend's name, as `--backend` takes it where it can be asked for.
    pub fn backend(&self) -> &'static str {
        match self.info.backend {
            wgpu::Backend::Vulkan => "vulkan",
            wgpu::Backend::Gl => "gl",
            wgpu::Backend::Metal => "metal",
            wgpu::Backend::Dx12 => "dx12",
            _ => "other",
        }
    }

    /// Whether this is a software rasterizer (lavapipe) rather than a GPU.
    pub fn is_software(&self) -> bool {
        self.info.device_type == DeviceType::Cpu
    }
}
