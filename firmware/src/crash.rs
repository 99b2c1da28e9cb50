//! The images' exception handlers, defined once for both: HardFault, the
//! non-maskable interrupt (NMI) and cortex-m-rt's `DefaultHandler`, which
//! every other exception and every interrupt without a handler of its own
//! reaches (MemManage, BusFault, UsageFault, SVCall, DebugMonitor, PendSV,
//! SysTick, and any device interrupt but the image's own).
//!
//! [`crash_handlers!`](crate::crash_handlers) defines the three, and each
//! calls the one function the image names with the [`Exception`] it came
//! from. That function (`crashed` in `src/main.rs` and in
//! `src/bin/selftest.rs`) puts the image's valves in the safe state first,
//! as its panic handler does, and never returns.

/// The exception that entered a crash handler.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Exception {
    /// HardFault, with the program counter stacked when it was taken.
    HardFault {
        /// The stacked program counter (the faulting instruction, or the
        /// one after it for an imprecise fault).
        pc: u32,
    },
    /// The non-maskable interrupt (on the STM32F405 also the clock security
    /// system's: the crystal failed).
    Nmi,
    /// Any other exception or interrupt without a handler of its own.
    Unhandled {
        /// As cortex-m-rt's `DefaultHandler` reports it: the active vector
        /// minus 16, so −12 is MemManage, −11 BusFault, −10 UsageFault, −5
        /// SVCall, −4 DebugMonitor, −2 PendSV, −1 SysTick, and 0 or more a
        /// device interrupt's number.
        irqn: i16,
    },
}

impl core::fmt::Display for Exception {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Exception::HardFault { pc } => write!(f, "hard fault at pc {pc:#010x}"),
            Exception::Nmi => f.write_str("NMI"),
            Exception::Unhandled { irqn } => write!(f, "unhandled exception (irqn {irqn})"),
        }
    }
}

/// Define the image's `HardFault`, `NonMaskableInt` (the NMI) and
/// `DefaultHandler`, each calling `$crashed` (a `fn(Exception) -> !` of the
/// image) with the [`Exception`] that entered it. Invoke it once, at the
/// image's top level; the image must depend on `cortex-m-rt`.
///
/// `$crashed` must put the valves safe before anything else, and must not
/// take a critical section or a lock (an NMI preempts them), allocate or
/// panic.
#[macro_export]
macro_rules! crash_handlers {
    ($crashed:path) => {
        // cortex-m-rt requires these three handlers to be `unsafe fn`.
        #[allow(unsafe_code)]
        #[::cortex_m_rt::exception]
        unsafe fn HardFault(frame: &::cortex_m_rt::ExceptionFrame) -> ! {
            $crashed($crate::crash::Exception::HardFault { pc: frame.pc() })
        }

        #[allow(unsafe_code)]
        #[::cortex_m_rt::exception]
        unsafe fn NonMaskableInt() -> ! {
            $crashed($crate::crash::Exception::Nmi)
        }

        #[allow(unsafe_code)]
        #[::cortex_m_rt::exception]
        unsafe fn DefaultHandler(irqn: i16) -> ! {
            $crashed($crate::crash::Exception::Unhandled { irqn })
        }
    };
}

#[cfg(test)]
mod tests {
    use super::Exception;

    #[test]
    fn each_exception_names_itself() {
        let text = |e: Exception| std::format!("{e}");
        assert_eq!(
            text(Exception::HardFault { pc: 0x0800_0abc }),
            "hard fault at pc 0x08000abc"
        );
        assert_eq!(text(Exception::Nmi), "NMI");
        assert_eq!(
            text(Exception::Unhandled { irqn: -2 }),
            "unhandled exception (irqn -2)"
        );
    }
}
