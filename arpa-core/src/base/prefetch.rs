//! A cache hint for the CPU backends: start loading a value's memory before it is read.

/// Asks the CPU to start loading the cache lines holding `value` (its first and last byte;
/// enough for values of up to two 64-byte lines, which is what the per-hit and per-candidate
/// records are). A hint only: no effect on results, never faults; a no-op off x86-64.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (value as *const T).cast::<i8>();
        let last = p.wrapping_add(core::mem::size_of::<T>().saturating_sub(1));
        // SAFETY: SSE is part of every x86-64 CPU; a prefetch reads nothing into the
        // program and never faults, whatever the address.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(last);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
