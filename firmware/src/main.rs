//! The sleeve firmware (STM32F405RG). Build inside `firmware/`: `cargo run --release`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod hw;

#[cfg(target_os = "none")]
use defmt_rtt as _;

#[cfg(target_os = "none")]
#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    hw::run(spawner).await
}

/// On the host the binary only says where the real one is; the logic's tests run
/// with `cargo test -p sleeve-firmware`.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("sleeve-firmware runs on the STM32F405RG: cd firmware && cargo run --release");
}
