//! The stack's high-water mark. cortex-m-rt's `paint-stack` fills the whole stack region
//! (`_stack_end` up to `_stack_start`, from its linker script) with
//! [`STACK_PAINT_VALUE`] before `main` runs; the deepest word no longer holding it
//! marks how far the stack ever grew. [`repaint`] paints the free part again, so that
//! the next reading is the mark of what ran after it.

use cortex_m_rt::STACK_PAINT_VALUE;

extern "C" {
    /// Top of the stack (its initial pointer; the stack grows down from here).
    static _stack_start: u32;
    /// Lowest address the stack may reach (the end of `.bss` and `.uninit`).
    static _stack_end: u32;
}

/// Bytes left unpainted below the stack pointer by [`repaint`]: room for the frame of
/// the painting loop itself, should the compiler spill below the pointer it read.
const REPAINT_MARGIN_BYTES: usize = 256;

/// How much of the stack was used.
pub struct StackUse {
    /// Bytes between the top of the stack and the deepest word written.
    pub used_bytes: usize,
    /// Bytes the stack region has.
    pub size_bytes: usize,
}

fn top() -> usize {
    core::ptr::addr_of!(_stack_start) as usize
}

fn bottom() -> usize {
    core::ptr::addr_of!(_stack_end) as usize
}

/// Scans the painted stack from its bottom up to the first word written.
pub fn high_water_mark() -> StackUse {
    let mut at = bottom();
    // SAFETY: every word in [bottom, top) is RAM the linker script gives the stack, and
    // it is only read.
    while at < top() && unsafe { core::ptr::read_volatile(at as *const u32) } == STACK_PAINT_VALUE {
        at += core::mem::size_of::<u32>();
    }
    StackUse {
        used_bytes: top() - at,
        size_bytes: top() - bottom(),
    }
}

/// Paints the free stack again: from its bottom up to [`REPAINT_MARGIN_BYTES`] below
/// the current stack pointer.
pub fn repaint() {
    let sp = cortex_m::register::msp::read() as usize;
    let end = sp.saturating_sub(REPAINT_MARGIN_BYTES) & !(core::mem::size_of::<u32>() - 1);
    let mut at = bottom();
    while at < end {
        // SAFETY: [bottom, sp) is stack RAM below the stack pointer: nothing uses it
        // (no interrupts are enabled), and the words are aligned.
        unsafe { core::ptr::write_volatile(at as *mut u32, STACK_PAINT_VALUE) };
        at += core::mem::size_of::<u32>();
    }
}
