//! Where the networks run. burn's Flex backend on the CPU is always built; the crate's `wgpu`
//! and `cuda` features add burn's CubeCL backend, which runs the same networks on a GPU
//! (wgpu: Vulkan, Metal or DX12 through the `wgpu` crate; cuda: NVIDIA's driver). The physics
//! op ([`crate::physics`]) runs on the host whatever the device: its input is read back from
//! the device, its value and gradient written to it.
//!
//! Names: `cpu` (Flex), `wgpu` (the adapter wgpu prefers; `CUBECL_WGPU_DEFAULT_DEVICE`
//! overrides it), `cuda` or `cuda:N` (GPU N).

use crate::error::{LearnError, Result};
use burn::tensor::Device;

/// The device named `name` (module docs); an error names the feature a build lacks.
pub fn parse(name: &str) -> Result<Device> {
    let lower = name.trim().to_ascii_lowercase();
    match lower.as_str() {
        "cpu" | "flex" => Ok(Device::flex()),
        "wgpu" => wgpu(),
        _ => match lower.strip_prefix("cuda") {
            Some("") => cuda(0),
            Some(index) => match index.strip_prefix(':').map(str::parse::<usize>) {
                Some(Ok(i)) => cuda(i),
                _ => Err(unknown(name)),
            },
            None => Err(unknown(name)),
        },
    }
}

fn unknown(name: &str) -> LearnError {
    LearnError::invalid(
        "device",
        format!("\"{name}\": expected cpu, wgpu, cuda or cuda:N"),
    )
}

#[cfg(feature = "wgpu")]
fn wgpu() -> Result<Device> {
    Ok(Device::wgpu(burn::tensor::DeviceKind::DefaultDevice))
}

#[cfg(not(feature = "wgpu"))]
fn wgpu() -> Result<Device> {
    Err(missing("wgpu"))
}

#[cfg(feature = "cuda")]
fn cuda(index: usize) -> Result<Device> {
    Ok(Device::cuda(index))
}

#[cfg(not(feature = "cuda"))]
fn cuda(_index: usize) -> Result<Device> {
    Err(missing("cuda"))
}

#[cfg(not(all(feature = "wgpu", feature = "cuda")))]
fn missing(feature: &str) -> LearnError {
    LearnError::invalid(
        "device",
        format!(
            "{feature}: this build has no {feature} backend; build it with \
             `cargo build --release -p musculo-learn --features {feature}`"
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_or_say_what_is_missing() {
        assert!(parse("cpu").unwrap() == Device::flex());
        assert!(parse(" Flex ").unwrap() == Device::flex());
        for bad in ["gpu", "cuda:x", "cuda0", ""] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains("expected cpu, wgpu, cuda"), "{bad}: {e}");
        }
        #[cfg(not(feature = "cuda"))]
        assert!(
            parse("cuda:1")
                .unwrap_err()
                .to_string()
                .contains("--features cuda")
        );
        #[cfg(not(feature = "wgpu"))]
        assert!(
            parse("wgpu")
                .unwrap_err()
                .to_string()
                .contains("--features wgpu")
        );
    }
}
