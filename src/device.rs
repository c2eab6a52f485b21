//! Where the generator runs: the device a user names (`--device cpu|flex|wgpu|cuda`), the probes
//! that turn a missing GPU or driver into a one-line error, and the chunk sizes per device.

use std::str::FromStr;

use burn::prelude::*;

use crate::error::{Error, Result};
use crate::input_error;

/// Where the generator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceChoice {
    /// The fused CPU evaluator (fastest on a CPU).
    Cpu,
    /// burn's flex CPU backend (the same math through the framework; for checks and training).
    Flex,
    /// burn's wgpu backend (Vulkan, Metal, DX12; lavapipe without a GPU).
    Wgpu,
    /// burn's CUDA backend (NVIDIA GPUs); needs a build with `--features cuda`.
    Cuda,
}

impl FromStr for DeviceChoice {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "cpu" => Ok(Self::Cpu),
            "flex" => Ok(Self::Flex),
            "wgpu" | "gpu" => Ok(Self::Wgpu),
            "cuda" => Ok(Self::Cuda),
            other => Err(input_error!(
                "unknown device '{other}'; use cpu, flex, wgpu or cuda"
            )),
        }
    }
}

impl DeviceChoice {
    /// The burn device for this choice (`None` for the fused CPU path). wgpu is probed here so a
    /// machine without an adapter gets an error instead of a panic on first use.
    pub fn burn_device(&self) -> Result<Option<Device>> {
        match self {
            Self::Cpu => Ok(None),
            Self::Flex => Ok(Some(Device::flex())),
            Self::Wgpu => wgpu_device().map(Some),
            Self::Cuda => cuda_device().map(Some),
        }
    }

    /// The best device present for training: CUDA where it starts, else wgpu where it sees a
    /// real GPU (not only software adapters such as lavapipe or llvmpipe), else flex (the CPU).
    pub fn best_for_training() -> Self {
        if Self::Cuda.burn_device().is_ok() {
            Self::Cuda
        } else if wgpu_has_gpu() && Self::Wgpu.burn_device().is_ok() {
            Self::Wgpu
        } else {
            Self::Flex
        }
    }

    /// `--device NAME` on every command: `auto` (or nothing) is the best device present, the
    /// same on every command ([`DeviceChoice::best_for_training`], with the CPU as its fused
    /// path); any other name as [`FromStr`] reads it.
    pub fn resolve(name: &str) -> Result<Self> {
        match name.to_ascii_lowercase().as_str() {
            "" | "auto" => Ok(match Self::best_for_training() {
                Self::Flex => Self::Cpu,
                gpu => gpu,
            }),
            other => other.parse(),
        }
    }

    /// [`DeviceChoice::resolve`] for training, where the CPU is burn's flex backend (its
    /// steps fused where they can be).
    pub fn for_training(name: &str) -> Result<Self> {
        Ok(match Self::resolve(name)? {
            Self::Cpu => Self::Flex,
            other => other,
        })
    }

    /// The device training uses: flex stands in for the fused CPU path, which has no backward.
    pub fn training_device(&self) -> Result<Device> {
        Ok(self.burn_device()?.unwrap_or_else(Device::flex))
    }
}

/// Whether every wgpu adapter on this machine is a software one (lavapipe, WARP): wgpu then
/// works but runs on the CPU, far slower than `--device cpu`.
#[cfg(feature = "wgpu")]
pub fn wgpu_is_software() -> bool {
    use burn::tensor::wgpu::wgpu;
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle();
    descriptor.backends = wgpu::Backends::PRIMARY;
    let instance = wgpu::Instance::new(descriptor);
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY));
    !adapters.is_empty()
        && adapters
            .iter()
            .all(|a| a.get_info().device_type == wgpu::DeviceType::Cpu)
}

/// A build without the `wgpu` feature has no wgpu adapter, software or not.
#[cfg(not(feature = "wgpu"))]
pub fn wgpu_is_software() -> bool {
    false
}

/// Whether wgpu sees a real GPU (discrete, integrated or virtual) on its primary backends
/// (Vulkan, Metal, DX12), where every GPU shows up: a machine with only software adapters
/// (lavapipe, WARP) has none. GL is not asked: its EGL probe prints to stderr on headless
/// machines, and a GPU reachable only through GL is left to `--device wgpu`.
#[cfg(feature = "wgpu")]
pub fn wgpu_has_gpu() -> bool {
    use burn::tensor::wgpu::wgpu;
    if !gpu_device_node_present() {
        return false; // no probe: Mesa's drivers print warnings to stderr on headless machines
    }
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle();
    descriptor.backends = wgpu::Backends::PRIMARY;
    let instance = wgpu::Instance::new(descriptor);
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY));
    adapters.iter().any(|a| {
        matches!(
            a.get_info().device_type,
            wgpu::DeviceType::DiscreteGpu
                | wgpu::DeviceType::IntegratedGpu
                | wgpu::DeviceType::VirtualGpu
        )
    })
}

/// A build without the `wgpu` feature has no wgpu adapter.
#[cfg(not(feature = "wgpu"))]
pub fn wgpu_has_gpu() -> bool {
    false
}

/// On Linux, whether the kernel shows a GPU at all (a DRM render node or an NVIDIA device);
/// elsewhere, true (wgpu is asked).
pub fn gpu_device_node_present() -> bool {
    if !cfg!(target_os = "linux") {
        return true;
    }
    let render_node = std::fs::read_dir("/dev/dri")
        .into_iter()
        .flatten()
        .flatten()
        .any(|e| e.file_name().to_string_lossy().starts_with("renderD"));
    render_node || std::path::Path::new("/dev/nvidia0").exists()
}

/// The CUDA device, probed once per process, so a machine without a driver or GPU gets an
/// error instead of a panic on first use.
#[cfg(feature = "cuda")]
pub fn cuda_device() -> Result<Device> {
    static DEVICE: std::sync::OnceLock<std::result::Result<Device, String>> =
        std::sync::OnceLock::new();
    DEVICE.get_or_init(probe_cuda).clone().map_err(|e| {
        input_error!("--device cuda: no usable CUDA device ({e}); check the NVIDIA driver (nvidia-smi) or use --device wgpu or cpu")
    })
}

/// The first CUDA device and a one-element round trip through it. CubeCL's CUDA runtime lists
/// no device where the driver library or the card is missing (it looks for the library before
/// loading it), so the common failures are errors; a driver that loads but fails later still
/// panics on burn's server thread, which reaches this one as a failed round trip or an unwind.
/// (burn's `Device::enumerate` would also start the wgpu runtime to list every device.)
#[cfg(feature = "cuda")]
fn probe_cuda() -> std::result::Result<Device, String> {
    if cubecl::device::Device::cuda(0).is_err() {
        return Err("the NVIDIA driver or a CUDA device is missing".into());
    }
    let round_trip = std::panic::catch_unwind(|| {
        let device = Device::cuda(0);
        let one = Tensor::<1>::from_floats([1.0f32].as_slice(), &device);
        one.try_into_vec_as::<f32>().map(|_| device)
    });
    match round_trip {
        Ok(Ok(device)) => Ok(device),
        Ok(Err(e)) => Err(format!("{e:?}")),
        Err(_) => Err("CUDA initialisation failed".into()),
    }
}

/// Without the `cuda` feature, `--device cuda` says how to get it.
#[cfg(not(feature = "cuda"))]
pub fn cuda_device() -> Result<Device> {
    Err(input_error!(
        "--device cuda: this ipfn was built without CUDA; reinstall with `cargo install-cuda` (the CUDA build) from the project's folder, or use --device wgpu"
    ))
}

/// Without the `wgpu` feature, `--device wgpu` says how to get it.
#[cfg(not(feature = "wgpu"))]
pub fn wgpu_device() -> Result<Device> {
    Err(input_error!(
        "--device wgpu: this ipfn was built without wgpu; reinstall with `cargo install --path .` (wgpu is a default feature), or use --device cpu"
    ))
}

/// The wgpu device, initialised once per process.
#[cfg(feature = "wgpu")]
pub fn wgpu_device() -> Result<Device> {
    static DEVICE: std::sync::OnceLock<std::result::Result<Device, String>> =
        std::sync::OnceLock::new();
    DEVICE
        .get_or_init(|| {
            Device::wgpu_options()
                .init()
                .map_err(|e| e.to_string().split_whitespace().collect::<Vec<_>>().join(" "))
        })
        .clone()
        .map_err(|e| {
            input_error!("--device wgpu: no usable GPU adapter ({e}); install Vulkan drivers (e.g. mesa-vulkan-drivers) or use --device cpu")
        })
}

/// Points per burn forward pass on a GPU: bounds device memory (`width` activations per point)
/// while keeping launches few.
pub const GPU_CHUNK_POINTS: usize = 1 << 16;
/// Points per burn forward pass on flex: activations stay in cache (`ipfn bench`: 1024² takes
/// half the time it takes with 65,536-point chunks).
pub const FLEX_CHUNK_POINTS: usize = 1 << 12;

impl DeviceChoice {
    /// Points per burn forward pass on this device.
    pub fn chunk_points(&self) -> usize {
        match self {
            Self::Cpu | Self::Flex => FLEX_CHUNK_POINTS,
            Self::Wgpu | Self::Cuda => GPU_CHUNK_POINTS,
        }
    }
}
