//! Board constants shared by the firmware binary (`src/main.rs`) and the on-target test
//! suite (`tests/on_target.rs`), which include this file with `#[path]`; not part of the core
//! library.

use embassy_stm32::Config;

/// Settings flash (offsets from the flash base): the last eight 2 KiB pages of bank 2
/// (dual-bank mode, the G474RE's factory setting), 0x0807C000..0x08080000. The image is
/// confined to bank 1 by `memory.x`, so erasing these pages never stalls the tick
/// (read-while-write); the whole-flash `Flash` driver erases without a critical section.
pub const SETTINGS_FLASH: core::ops::Range<u32> = (512 - 16) * 1024..512 * 1024;

/// The clock tree: HSI16 ÷ 4 × 85 ÷ 2 = 170 MHz system clock (PLL1_R); DMA interrupts at
/// P1 (below the tick's P0).
pub fn clock_config() -> Config {
    let mut config = Config::default();
    {
        use embassy_stm32::rcc::*;
        config.rcc.hsi = true;
        config.rcc.pll = Some(Pll {
            source: PllSource::HSI,
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL85,
            divp: None,
            divq: None,
            divr: Some(PllRDiv::DIV2),
        });
        config.rcc.sys = Sysclk::PLL1_R;
    }
    config.bdma_interrupt_priority = embassy_stm32::interrupt::Priority::P1;
    config
}
