//! The GPU: picking an adapter (discrete > integrated > software, or the user's choice) and
//! opening a device on it.

use std::fmt::Write;

/// An open device and the adapter it runs on.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// The adapter supports timestamp queries inside passes (used by `bench`).
    pub timestamps: bool,
}

/// Why no device could be opened.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter that can run compute shaders was found.\n{tried}\n{HINT}")]
    NoAdapter { tried: String },
    #[error(
        "no adapter matches `{selector}`.\n{tried}\nSelect one by a part of its name, its backend (vulkan, gl, metal, dx12), its type (cpu, discrete, integrated) or its number in `termtrace adapters`, or the native CPU tracer by `cpu-native`."
    )]
    NoMatch { selector: String, tried: String },
    #[error("could not open a device on {adapter}: {message}")]
    Device { adapter: String, message: String },
}

const HINT: &str = "How to fix: on a machine without a GPU install Mesa's software adapters, \
    `apt-get install mesa-vulkan-drivers` (lavapipe, Vulkan; fastest) or `libegl-mesa0 \
    libgl1-mesa-dri` (llvmpipe, OpenGL). On a GPU machine install its Vulkan driver and the \
    loader (`libvulkan1`). WGPU_BACKEND=vulkan|gl restricts the backends tried.";

/// Storage buffers the tracer binds in one stage; two more on lavapipe, where the scene's and
/// the dispatch's values are storage buffers too ([`super::Values`]).
const STORAGE_BUFFERS_NEEDED: u32 = 15;

/// One line naming an adapter: `NVIDIA H100 (Vulkan, DiscreteGpu, driver 550.1)`.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    let mut s = format!("{} ({:?}, {:?}", info.name, info.backend, info.device_type);
    let driver = format!("{} {}", info.driver, info.driver_info);
    if !driver.trim().is_empty() {
        let _ = write!(s, ", {}", driver.trim());
    }
    s.push(')');
    s
}

fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    // WGPU_BACKEND, when set, wins; otherwise the backends asked for.
    if std::env::var_os("WGPU_BACKEND").is_none() {
        desc.backends = backends;
    }
    wgpu::Instance::new(desc)
}

/// Every adapter of `backends`, with the instance that owns them.
fn enumerate(backends: wgpu::Backends) -> Vec<wgpu::Adapter> {
    let inst = instance(backends);
    pollster::block_on(inst.enumerate_adapters(backends))
}

/// Mesa's Vulkan software adapter (a CPU adapter on Vulkan), whose quirks [`super::Values`]
/// works around.
pub fn is_lavapipe(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu && info.backend == wgpu::Backend::Vulkan
}

/// Whether the tracer can run on an adapter; the reason when it cannot.
fn unusable(a: &wgpu::Adapter) -> Option<String> {
    let caps = a.get_downlevel_capabilities();
    if !caps.flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS) {
        return Some("no compute shaders".into());
    }
    let n = a.limits().max_storage_buffers_per_shader_stage;
    let needed = STORAGE_BUFFERS_NEEDED + if is_lavapipe(&a.get_info()) { 2 } else { 0 };
    if n < needed {
        return Some(format!("{n} storage buffers per stage, {needed} needed"));
    }
    None
}

/// Preference: device type first, then backend.
fn rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    use wgpu::{Backend, DeviceType};
    let t = match info.device_type {
        DeviceType::DiscreteGpu => 0,
        DeviceType::IntegratedGpu => 1,
        DeviceType::VirtualGpu => 2,
        DeviceType::Cpu => 3,
        DeviceType::Other => 4,
    };
    let b = match info.backend {
        Backend::Vulkan | Backend::Metal | Backend::Dx12 => 0,
        Backend::Gl => 1,
        _ => 2,
    };
    (t, b)
}

/// Every adapter on this machine, best first, with the reason each unusable one is not.
pub fn list_adapters() -> Vec<(wgpu::AdapterInfo, Option<String>)> {
    let mut all: Vec<_> = enumerate(wgpu::Backends::all())
        .iter()
        .map(|a| (a.get_info(), unusable(a)))
        .collect();
    all.sort_by_key(|(i, bad)| (bad.is_some(), rank(i)));
    all
}

fn matches(info: &wgpu::AdapterInfo, index: usize, selector: &str) -> bool {
    let s = selector.to_lowercase();
    if s.parse::<usize>() == Ok(index) {
        return true;
    }
    let backend = format!("{:?}", info.backend).to_lowercase();
    let kind = format!("{:?}", info.device_type).to_lowercase();
    info.name.to_lowercase().contains(&s)
        || backend == s
        || (s == "gles" && backend == "gl")
        || kind == s
        || kind.trim_end_matches("gpu") == s
}

fn tried_list(adapters: &[(wgpu::AdapterInfo, Option<String>)], backends: &str) -> String {
    let mut s = format!("Backends tried: {backends}.");
    if adapters.is_empty() {
        s.push_str(" No adapters were found.");
    } else {
        s.push_str(" Adapters found:");
        for (i, (info, bad)) in adapters.iter().enumerate() {
            let _ = write!(s, "\n  [{i}] {}", describe(info));
            if let Some(b) = bad {
                let _ = write!(s, ": unusable, {b}");
            }
        }
    }
    s
}

/// Picks the adapter: the best usable one, or the one `selector` names.
pub fn select_adapter(selector: Option<&str>) -> Result<wgpu::Adapter, GpuError> {
    let selector = selector.map(str::trim).filter(|s| !s.is_empty());
    // The native backends first; the GL backend is initialised only when needed, since it is
    // slow to start and noisy on machines without a display.
    let mut passes = vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY];
    if selector.is_some() {
        passes = vec![wgpu::Backends::all()];
    }
    let mut seen: Vec<(wgpu::AdapterInfo, Option<String>)> = Vec::new();
    let mut names = Vec::new();
    for backends in passes {
        names.push(format!("{backends:?}"));
        let mut adapters = enumerate(backends);
        adapters.sort_by_key(|a| (unusable(a).is_some(), rank(&a.get_info())));
        for (i, a) in adapters.into_iter().enumerate() {
            let info = a.get_info();
            let bad = unusable(&a);
            let wanted = selector.is_none_or(|s| matches(&info, i, s));
            if wanted && bad.is_none() {
                return Ok(a);
            }
            seen.push((info, bad));
        }
    }
    let tried = tried_list(&seen, &names.join(", then "));
    Err(match selector {
        Some(s) => GpuError::NoMatch {
            selector: s.to_string(),
            tried,
        },
        None => GpuError::NoAdapter { tried },
    })
}

/// Every usable hardware GPU (not a software adapter) on the backend of the best one, best
/// first: `--adapter all`. One backend only, so that no GPU is counted twice (a GPU can show
/// up on Vulkan and on GL).
pub fn hardware_adapters() -> Vec<wgpu::Adapter> {
    let mut adapters: Vec<wgpu::Adapter> = enumerate(wgpu::Backends::PRIMARY)
        .into_iter()
        .filter(|a| unusable(a).is_none() && a.get_info().device_type != wgpu::DeviceType::Cpu)
        .collect();
    adapters.sort_by_key(|a| rank(&a.get_info()));
    let Some(best) = adapters.first().map(|a| a.get_info().backend) else {
        return adapters;
    };
    adapters.retain(|a| a.get_info().backend == best);
    adapters
}

impl GpuContext {
    /// Opens a device on the adapter `selector` names, or on the best one.
    pub fn new(selector: Option<&str>) -> Result<GpuContext, GpuError> {
        Self::on(select_adapter(selector)?)
    }

    /// Opens a device on `adapter`, with every limit the adapter offers.
    pub fn on(adapter: wgpu::Adapter) -> Result<GpuContext, GpuError> {
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut required_features = wgpu::Features::empty();
        if timestamps {
            required_features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let desc = wgpu::DeviceDescriptor {
            label: Some("termtrace"),
            required_features,
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&desc)).map_err(|e| GpuError::Device {
                adapter: describe(&info),
                message: e.to_string(),
            })?;
        tracing::info!("device opened on {}", describe(&info));
        Ok(GpuContext {
            device,
            queue,
            info,
            timestamps,
        })
    }

    /// `describe` of this context's adapter.
    pub fn adapter_name(&self) -> String {
        describe(&self.info)
    }

    /// True on a CPU (software) adapter such as llvmpipe.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }
}
