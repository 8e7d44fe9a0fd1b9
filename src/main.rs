//! odocal firmware entry point (RTIC 2, STM32F407). Wiring only; logic lives in the library.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the odocal firmware runs on the STM32F407; on the host, use `cargo sim`");
}
