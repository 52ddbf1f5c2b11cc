//! On the chip (`thumbv7em-none-eabihf` under QEMU): the stages of [`spherecal_firmware::run`]
//! with their digest printed over semihosting, then the image's flash and static RAM, the
//! stack's high-water mark (painted) and the instructions per data packet (SysTick under QEMU's
//! `-icount shift=0`: one instruction a nanosecond of virtual time); exit 0, or 1 on a panic.
//! On the host: the same digest, printed the same way.

#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    let d = spherecal_firmware::run(&mut (), &mut ());
    spherecal_firmware::lines(&d, |name, v| println!("{name} {v}"));
}

#[cfg(target_os = "none")]
mod chip {
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};

    /// What an unused stack word holds.
    const STACK_PAINT: u32 = 0x5a5a_a5a5;
    /// How far below the stack pointer at entry the stack is painted [bytes] (the budget: a
    /// deeper stack reads as this, and fails it).
    const PAINTED: usize = 512 * 1024;
    /// Where RAM starts (memory.x).
    const RAM_ORIGIN: usize = 0x2000_0000;

    extern "C" {
        static __sheap: u32;
        static _stack_start: u32;
        static __sidata: u32;
        static __sdata: u32;
        static __edata: u32;
    }

    /// SysTick ticks over the aligner's work.
    struct Ticks {
        total: u64,
        at: u32,
        packets: u64,
    }

    fn now() -> u32 {
        cortex_m::peripheral::SYST::get_current()
    }

    impl spherecal_firmware::Meter for Ticks {
        fn start(&mut self) {
            self.at = now();
        }
        fn stop(&mut self) {
            // The counter counts down from 2^24 - 1 and wraps.
            self.total += u64::from(self.at.wrapping_sub(now()) & 0x00ff_ffff);
            self.packets += 1;
        }
    }

    /// Instructions per SysTick tick (QEMU's MPS2 SysTick runs at 25 MHz: with `-icount
    /// shift=0`, 40): a loop of exactly two instructions (`subs`, `bne`) run 2^20 times.
    fn calibrate() -> u64 {
        let n: u32 = 1 << 20;
        let a = now();
        // SAFETY: a register-only countdown loop; no memory is touched.
        unsafe {
            core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
        }
        let ticks = u64::from(a.wrapping_sub(now()) & 0x00ff_ffff).max(1);
        (2 * u64::from(n) + ticks / 2) / ticks
    }

    fn addr(s: &u32) -> usize {
        s as *const u32 as usize
    }

    #[entry]
    fn main() -> ! {
        let mut p = cortex_m::Peripherals::take().expect("peripherals");
        // Paint the stack below here (what the run touches no longer holds the paint).
        let sp = cortex_m::register::msp::read() as usize;
        // SAFETY: the symbols are the linker's; only their addresses are taken.
        let (heap, top, sidata, sdata, edata) = unsafe {
            (
                addr(&__sheap),
                addr(&_stack_start),
                addr(&__sidata),
                addr(&__sdata),
                addr(&__edata),
            )
        };
        let low = sp.saturating_sub(PAINTED).max(heap);
        let mut w = low;
        while w + 4 <= sp - 256 {
            // SAFETY: between the end of .bss and 256 bytes below the live stack pointer: free
            // RAM no one else uses.
            unsafe { core::ptr::write_volatile(w as *mut u32, STACK_PAINT) };
            w += 4;
        }
        p.SYST.set_clock_source(SystClkSource::Core);
        p.SYST.set_reload(0x00ff_ffff);
        p.SYST.clear_current();
        p.SYST.enable_counter();
        let per_tick = calibrate();
        let mut ticks = Ticks {
            total: 0,
            at: 0,
            packets: 0,
        };
        let mut simplex = Ticks {
            total: 0,
            at: 0,
            packets: 0,
        };
        let d = spherecal_firmware::run(&mut ticks, &mut simplex);
        spherecal_firmware::lines(&d, |name, v| hprintln!("{} {}", name, v));
        // The lowest word that lost its paint.
        let mut used = low;
        while used < sp - 256 {
            // SAFETY: as above, reading what was painted.
            if unsafe { core::ptr::read_volatile(used as *const u32) } != STACK_PAINT {
                break;
            }
            used += 4;
        }
        hprintln!("flash {} bytes", sidata + (edata - sdata));
        hprintln!("ram {} bytes", heap - RAM_ORIGIN);
        hprintln!("stack {} bytes", top - used);
        hprintln!("instructions per systick tick {}", per_tick);
        hprintln!(
            "instructions per data packet {}",
            ticks.total * per_tick / ticks.packets.max(1)
        );
        hprintln!(
            "instructions per simplex iteration {} ({} returns)",
            simplex.total * per_tick / d.simplex_iterations.max(1),
            d.batch_returns
        );
        debug::exit(debug::EXIT_SUCCESS);
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        hprintln!("panic: {}", info);
        debug::exit(debug::EXIT_FAILURE);
        loop {
            cortex_m::asm::wfi();
        }
    }
}
