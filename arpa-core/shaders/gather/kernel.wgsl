// WGSL twin of arpa_core::gather::kernel: radial kernels normalised over the unit disc of filter
// space, evaluated at squared radius r2 (f32, like Kernel::eval). Self-contained.

// Kernel ids (arpa_core::gather::kernel::Kernel).
const ARPA_KERNEL_CONSTANT: u32 = 0u;
const ARPA_KERNEL_EPANECHNIKOV: u32 = 1u;
const ARPA_KERNEL_SILVERMAN: u32 = 2u;

const ARPA_FRAC_1_PI: f32 = 0.31830988618379067;

// K(r2) for r2 < 1, else 0 (NaN gives 0); per unit filter-space area.
fn arpa_kernel_eval(kernel: u32, r2_in: f32) -> f32 {
    if !(r2_in < 1.0) {
        return 0.0;
    }
    let s = 1.0 - max(r2_in, 0.0);
    switch kernel {
        case 0u: { return ARPA_FRAC_1_PI; }
        case 1u: { return 2.0 * ARPA_FRAC_1_PI * s; }
        default: { return 3.0 * ARPA_FRAC_1_PI * s * s; }
    }
}
