//! Mitsuba 3 `<spectrum>` values (a constant, `λ:v` pairs or a `.spd` file) turned into
//! linear sRGB exactly as Mitsuba 3's RGB variants (`scalar_rgb`, `llvm_ad_rgb`) do when they
//! load a scene, so that a scene renders with the colours Mitsuba would use.
//!
//! Mitsuba (3.9: `Properties::get_texture_impl` in `src/core/properties.cpp`,
//! `spectrum_list_to_srgb` in `src/core/spectrum.cpp`) integrates a sampled spectrum once, at
//! load time, into an `srgb` texture:
//!
//! * the spectrum is linearly interpolated between its samples and is **zero outside**
//!   `[λ_first, λ_last]` (not extended);
//! * it is read at 1000 evenly spaced wavelengths from 360 nm to 830 nm (both included),
//!   each weighted equally and multiplied by the CIE 1931 2° colour-matching functions (5 nm
//!   table, linear interpolation) and, **for reflectances only**, by the CIE D65 illuminant
//!   (scaled to unit luminance);
//! * the sum is scaled by 470 nm / 1000 / 106.7502593994140625 (so 1 per nm over the whole
//!   range has luminance Y ≈ 1) and taken from XYZ to linear sRGB (Rec. 709 primaries);
//! * a reflectance is then clipped to [0, 1], an emission only to ≥ 0 (Mitsuba warns).
//!
//! A constant skips all that: a reflectance `v` is (v, v, v); an emitted `v` is v·M·(1, 1, 1),
//! the colour of the equal-energy spectrum, ≈ v·(1.2048, 0.9483, 0.9089); neither is clamped.

use glam::DVec3;

/// How the spectrum is used, which decides Mitsuba's conversion details.
///
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SpectrumUse {
    /// A reflectance-like texture (`reflectance`, `specular_reflectance`, …; unitless in
    /// [0, 1]): weighted by D65 so that a flat 1 is white, clipped to [0, 1].
    Reflectance,
    /// Emission: spectral `radiance` (W/(m²·sr·nm)), `intensity` (W/(sr·nm)) or
    /// `irradiance` (W/(m²·nm)): not weighted by D65, negatives clipped to 0.
    Emission,
    /// An unbounded non-emissive parameter (conductor `eta`, `k`): weighted by D65 like a
    /// reflectance, only negatives clipped; a constant stays `(v, v, v)`.
    Unbounded,
}

/// A parsed spectrum.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Spectrum {
    /// The same value at every wavelength (`value="0.5"`).
    Constant(f64),
    /// `(wavelength in nm, value)` samples; from the parsers, at least two, finite, and with
    /// strictly increasing wavelengths. Zero outside the first..last wavelength.
    Sampled(Vec<(f64, f64)>),
}

/// The result of [`convert`]: the colour and whether Mitsuba would clamp it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Conversion {
    /// Linear sRGB, as Mitsuba stores it (after clamping).
    pub(crate) rgb: DVec3,
    /// The colour before clamping when Mitsuba would clamp it and warn "Spectrum: clamping
    /// out-of-gamut color"; `None` when it is kept as is.
    pub(crate) clamped_from: Option<DVec3>,
}

/// Parses Mitsuba's `value` attribute of a `<spectrum>`: "v" (constant) or
/// "λ1:v1, λ2:v2, ..." (nm, ascending).
///
/// Commas and white space both separate pairs, as in Mitsuba; a pair has no spaces around
/// its ':'. Non-finite numbers are rejected (Mitsuba would produce NaN colours).
pub(crate) fn parse_value(text: &str) -> Result<Spectrum, String> {
    let mut tokens = fields(text).peekable();
    let Some(first) = tokens.next() else {
        return Err("empty spectrum".into());
    };
    if tokens.peek().is_none() && !first.contains(':') {
        return Ok(Spectrum::Constant(number(first)?));
    }
    let mut samples = Vec::new();
    for token in std::iter::once(first).chain(tokens) {
        let pair = token
            .split_once(':')
            .filter(|(w, v)| !w.is_empty() && !v.is_empty() && !v.contains(':'));
        let Some((w, v)) = pair else {
            return Err(format!(
                "'{}' is not a wavelength:value pair",
                shorten(token)
            ));
        };
        samples.push((number(w)?, number(v)?));
    }
    checked(samples)
}

/// Parses a .spd file's bytes ("λ v" per line, '#' comments).
///
/// Wavelengths are in nm and must increase. Blank lines and text after '#' are skipped;
/// fields may be separated by white space or commas; fields after the second are ignored,
/// as Mitsuba ignores them. Errors name the line in the file.
pub(crate) fn parse_spd(bytes: &[u8]) -> Result<Spectrum, String> {
    let text = String::from_utf8_lossy(bytes);
    let mut samples = Vec::new();
    for (index, line) in text.split('\n').enumerate() {
        let content = line.split('#').next().unwrap_or_default();
        let mut parts = fields(content);
        let Some(w) = parts.next() else { continue };
        let at_line = |e: String| format!("line {}: {e}", index + 1);
        let Some(v) = parts.next() else {
            return Err(at_line(format!(
                "expected 'wavelength value', found only '{}'",
                shorten(w)
            )));
        };
        samples.push((number(w).map_err(at_line)?, number(v).map_err(at_line)?));
    }
    checked(samples)
}

/// Linear sRGB as Mitsuba's RGB variants make it, after Mitsuba's clamping (see
/// [`convert`] to also learn whether it clamped). Never panics; for hand-built samples that
/// the parsers would reject (unsorted, fewer than two, non-finite) the colour is unspecified.
#[cfg(test)]
pub(crate) fn to_linear_srgb(s: &Spectrum, usage: SpectrumUse) -> DVec3 {
    convert(s, usage).rgb
}

/// Linear sRGB as Mitsuba's RGB variants make it, and the unclamped colour when Mitsuba
/// would clamp (and warn about) it.
pub(crate) fn convert(s: &Spectrum, usage: SpectrumUse) -> Conversion {
    let samples = match s {
        Spectrum::Constant(v) => {
            // Mitsuba makes a `uniform` texture of a constant reflectance and an `srgb`
            // texture of v times the equal-energy colour for an emitter; no clamping.
            let rgb = match usage {
                SpectrumUse::Reflectance | SpectrumUse::Unbounded => DVec3::splat(*v),
                SpectrumUse::Emission => *v * xyz_to_srgb(DVec3::ONE),
            };
            return Conversion {
                rgb,
                clamped_from: None,
            };
        }
        Spectrum::Sampled(samples) => samples,
    };
    let rgb = xyz_to_srgb(integrate_xyz(samples, usage != SpectrumUse::Emission));
    let (low, high) = match usage {
        SpectrumUse::Reflectance => (0.0, 1.0),
        SpectrumUse::Emission | SpectrumUse::Unbounded => (0.0, f64::INFINITY),
    };
    if rgb.to_array().iter().any(|&c| c < low || c > high) {
        // Comparisons, not f64::clamp, so that NaN stays NaN as in Mitsuba.
        let clip = |c: f64| {
            if c < low {
                low
            } else if c > high {
                high
            } else {
                c
            }
        };
        let clipped = DVec3::new(clip(rgb.x), clip(rgb.y), clip(rgb.z));
        Conversion {
            rgb: clipped,
            clamped_from: Some(rgb),
        }
    } else {
        Conversion {
            rgb,
            clamped_from: None,
        }
    }
}

/// Splits on commas and white space, dropping empty fields.
fn fields(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
}

/// Parses one finite number.
fn number(token: &str) -> Result<f64, String> {
    match token.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("'{}' is not a finite number", shorten(token))),
        Err(_) => Err(format!("'{}' is not a number", shorten(token))),
    }
}

/// Cuts a token for an error message to at most 40 characters.
fn shorten(token: &str) -> String {
    match token.char_indices().nth(40) {
        Some((end, _)) => format!("{}…", &token[..end]),
        None => token.to_owned(),
    }
}

/// Checks what Mitsuba checks of a sampled spectrum: two samples or more, increasing
/// wavelengths.
fn checked(samples: Vec<(f64, f64)>) -> Result<Spectrum, String> {
    match samples.len() {
        0 => return Err("empty spectrum".into()),
        1 => return Err("a spectrum needs at least two wavelength:value samples".into()),
        _ => {}
    }
    if let Some(w) = samples.windows(2).find(|w| w[1].0 <= w[0].0) {
        return Err(format!(
            "wavelengths must increase: {} after {}",
            w[1].0, w[0].0
        ));
    }
    Ok(Spectrum::Sampled(samples))
}

/// Shortest wavelength of the CIE tables and of the integration, nm.
const CIE_MIN: f64 = 360.0;
/// Longest wavelength of the CIE tables and of the integration, nm.
const CIE_MAX: f64 = 830.0;
/// Entries per table: 360..=830 nm every 5 nm.
const CIE_SAMPLES: usize = 95;
/// Number of evenly spaced wavelengths Mitsuba sums over (a Riemann sum, not a quadrature
/// that weights the ends by half).
const STEPS: usize = 1000;
/// 1 / ∫ȳ(λ) dλ as Mitsuba takes it, 1/nm: a spectrum of 1 per nm then has luminance 1.
const CIE_Y_NORMALIZATION: f64 = 1.0 / 106.750_259_399_414_06; // = 106.7502593994140625
/// 1 / (the luminance of the tabulated D65), so that the weight D65(λ)·this has unit
/// luminance.
const D65_NORMALIZATION: f64 = 1.0 / 98.99741751876255;

/// XYZ → linear sRGB (Rec. 709 primaries, D65 white), in single precision as Mitsuba holds
/// it; rows give R, G, B.
const XYZ_TO_SRGB: [[f32; 3]; 3] = [
    [3.240479, -1.53715, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

/// Applies [`XYZ_TO_SRGB`] in double precision.
fn xyz_to_srgb(xyz: DVec3) -> DVec3 {
    let row = |r: [f32; 3]| DVec3::new(r[0].into(), r[1].into(), r[2].into()).dot(xyz);
    DVec3::new(
        row(XYZ_TO_SRGB[0]),
        row(XYZ_TO_SRGB[1]),
        row(XYZ_TO_SRGB[2]),
    )
}

/// ∫ s(λ) · (x̄, ȳ, z̄)(λ) · [D65(λ)] dλ over 360..830 nm as Mitsuba approximates it, already
/// scaled by [`CIE_Y_NORMALIZATION`].
fn integrate_xyz(samples: &[(f64, f64)], d65: bool) -> DVec3 {
    let (Some(&(first, _)), Some(&(last, _))) = (samples.first(), samples.last()) else {
        return DVec3::ZERO;
    };
    let mut xyz = DVec3::ZERO;
    for i in 0..STEPS {
        let w = CIE_MIN + (i as f64 / (STEPS - 1) as f64) * (CIE_MAX - CIE_MIN);
        if !(w >= first && w <= last) {
            continue; // zero outside the given wavelengths
        }
        let weight = if d65 { d65_at(w) } else { 1.0 };
        xyz += cie_xyz_at(w) * sample_at(samples, w) * weight;
    }
    xyz * ((CIE_MAX - CIE_MIN) * CIE_Y_NORMALIZATION / STEPS as f64)
}

/// The spectrum at `w` nm (within its range), linear between neighbouring samples.
fn sample_at(samples: &[(f64, f64)], w: f64) -> f64 {
    let n = samples.len();
    if n < 2 {
        return samples.first().map_or(0.0, |s| s.1);
    }
    // Last sample at or below w, kept so that a next one exists.
    let i = samples
        .partition_point(|s| s.0 <= w)
        .saturating_sub(1)
        .min(n - 2);
    let ((w0, v0), (w1, v1)) = (samples[i], samples[i + 1]);
    if w0 == w1 {
        return v0; // only in hand-built, invalid input
    }
    ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1)
}

/// Where `w` nm falls in the 5 nm tables: the lower entry and the weight of the upper one;
/// `None` outside 360..=830 nm, where the tables are zero.
fn table_position(w: f64) -> Option<(usize, f64)> {
    if !(CIE_MIN..=CIE_MAX).contains(&w) {
        return None;
    }
    let t = (w - CIE_MIN) * ((CIE_SAMPLES - 1) as f64 / (CIE_MAX - CIE_MIN));
    let i = (t as usize).min(CIE_SAMPLES - 2);
    Some((i, t - i as f64))
}

/// Linear interpolation in a table stored as Mitsuba stores it (single precision).
fn lerp_table(table: &[f32; CIE_SAMPLES], i: usize, f: f64) -> f64 {
    (1.0 - f) * f64::from(table[i]) + f * f64::from(table[i + 1])
}

/// The CIE 1931 2° colour-matching functions x̄, ȳ, z̄ at `w` nm.
fn cie_xyz_at(w: f64) -> DVec3 {
    match table_position(w) {
        Some((i, f)) => DVec3::new(
            lerp_table(&CIE_TABLES[0], i, f),
            lerp_table(&CIE_TABLES[1], i, f),
            lerp_table(&CIE_TABLES[2], i, f),
        ),
        None => DVec3::ZERO,
    }
}

/// The CIE D65 illuminant at `w` nm, scaled to unit luminance.
fn d65_at(w: f64) -> f64 {
    match table_position(w) {
        Some((i, f)) => lerp_table(&D65, i, f) * D65_NORMALIZATION,
        None => 0.0,
    }
}

/// [`CIE_X`], [`CIE_Y`], [`CIE_Z`] rounded to single precision, as Mitsuba holds them.
static CIE_TABLES: [[f32; CIE_SAMPLES]; 3] = [to_f32(&CIE_X), to_f32(&CIE_Y), to_f32(&CIE_Z)];

/// Rounds a table to single precision (the data are given as decimal doubles).
const fn to_f32(table: &[f64; CIE_SAMPLES]) -> [f32; CIE_SAMPLES] {
    let mut out = [0.0f32; CIE_SAMPLES];
    let mut i = 0;
    while i < CIE_SAMPLES {
        out[i] = table[i] as f32;
        i += 1;
    }
    out
}

/// CIE 1931 2° x̄ at 360, 365, …, 830 nm (CIE 015 / CVRL data).
#[rustfmt::skip]
const CIE_X: [f64; CIE_SAMPLES] = [
    0.0001299, 0.0002321, 0.0004149, 0.0007416, 0.001368, 0.002236, // 360 nm
    0.004243, 0.00765, 0.01431, 0.02319, 0.04351, 0.07763, // 390 nm
    0.13438, 0.21477, 0.2839, 0.3285, 0.34828, 0.34806, // 420 nm
    0.3362, 0.3187, 0.2908, 0.2511, 0.19536, 0.1421, // 450 nm
    0.09564, 0.05795001, 0.03201, 0.0147, 0.0049, 0.0024, // 480 nm
    0.0093, 0.0291, 0.06327, 0.1096, 0.1655, 0.2257499, // 510 nm
    0.2904, 0.3597, 0.4334499, 0.5120501, 0.5945, 0.6784, // 540 nm
    0.7621, 0.8425, 0.9163, 0.9786, 1.0263, 1.0567, // 570 nm
    1.0622, 1.0456, 1.0026, 0.9384, 0.8544499, 0.7514, // 600 nm
    0.6424, 0.5419, 0.4479, 0.3608, 0.2835, 0.2187, // 630 nm
    0.1649, 0.1212, 0.0874, 0.0636, 0.04677, 0.0329, // 660 nm
    0.0227, 0.01584, 0.01135916, 0.008110916, 0.005790346, 0.004109457, // 690 nm
    0.002899327, 0.00204919, 0.001439971, 0.0009999493, 0.0006900786, 0.0004760213, // 720 nm
    0.0003323011, 0.0002348261, 0.0001661505, 0.000117413, 0.00008307527, 0.00005870652, // 750 nm
    0.00004150994, 0.00002935326, 0.00002067383, 0.00001455977, 0.00001025398, 0.000007221456, // 780 nm
    0.000005085868, 0.000003581652, 0.000002522525, 0.000001776509, 0.000001251141, // 810 nm
];
/// CIE 1931 2° ȳ at 360, 365, …, 830 nm.
#[rustfmt::skip]
const CIE_Y: [f64; CIE_SAMPLES] = [
    0.000003917, 0.000006965, 0.00001239, 0.00002202, 0.000039, 0.000064, // 360 nm
    0.00012, 0.000217, 0.000396, 0.00064, 0.00121, 0.00218, // 390 nm
    0.004, 0.0073, 0.0116, 0.01684, 0.023, 0.0298, // 420 nm
    0.038, 0.048, 0.06, 0.0739, 0.09098, 0.1126, // 450 nm
    0.13902, 0.1693, 0.20802, 0.2586, 0.323, 0.4073, // 480 nm
    0.503, 0.6082, 0.71, 0.7932, 0.862, 0.9148501, // 510 nm
    0.954, 0.9803, 0.9949501, 1.0, 0.995, 0.9786, // 540 nm
    0.952, 0.9154, 0.87, 0.8163, 0.757, 0.6949, // 570 nm
    0.631, 0.5668, 0.503, 0.4412, 0.381, 0.321, // 600 nm
    0.265, 0.217, 0.175, 0.1382, 0.107, 0.0816, // 630 nm
    0.061, 0.04458, 0.032, 0.0232, 0.017, 0.01192, // 660 nm
    0.00821, 0.005723, 0.004102, 0.002929, 0.002091, 0.001484, // 690 nm
    0.001047, 0.00074, 0.00052, 0.0003611, 0.0002492, 0.0001719, // 720 nm
    0.00012, 0.0000848, 0.00006, 0.0000424, 0.00003, 0.0000212, // 750 nm
    0.00001499, 0.0000106, 0.0000074657, 0.0000052578, 0.0000037029, 0.0000026078, // 780 nm
    0.0000018366, 0.0000012934, 0.00000091093, 0.00000064153, 0.00000045181, // 810 nm
];
/// CIE 1931 2° z̄ at 360, 365, …, 830 nm.
#[rustfmt::skip]
const CIE_Z: [f64; CIE_SAMPLES] = [
    0.0006061, 0.001086, 0.001946, 0.003486, 0.006450001, 0.01054999, // 360 nm
    0.02005001, 0.03621, 0.06785001, 0.1102, 0.2074, 0.3713, // 390 nm
    0.6456, 1.0390501, 1.3856, 1.62296, 1.74706, 1.7826, // 420 nm
    1.77211, 1.7441, 1.6692, 1.5281, 1.28764, 1.0419, // 450 nm
    0.8129501, 0.6162, 0.46518, 0.3533, 0.272, 0.2123, // 480 nm
    0.1582, 0.1117, 0.07824999, 0.05725001, 0.04216, 0.02984, // 510 nm
    0.0203, 0.0134, 0.008749999, 0.005749999, 0.0039, 0.002749999, // 540 nm
    0.0021, 0.0018, 0.001650001, 0.0014, 0.0011, 0.001, // 570 nm
    0.0008, 0.0006, 0.00034, 0.00024, 0.00019, 0.0001, // 600 nm
    0.00004999999, 0.00003, 0.00002, 0.00001, 0.0, 0.0, // 630 nm
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, // 660 nm
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, // 690 nm
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, // 720 nm
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, // 750 nm
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, // 780 nm
    0.0, 0.0, 0.0, 0.0, 0.0, // 810 nm
];
/// CIE standard illuminant D65, relative spectral power (100 at 560 nm), at 360, 365, …,
/// 830 nm.
#[rustfmt::skip]
const D65: [f32; CIE_SAMPLES] = [
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482, 68.7015, // 360 nm
    82.7549, 87.1204, 91.486, 92.4589, 93.4318, 90.057, 86.6823, 95.7736, // 400 nm
    104.865, 110.936, 117.008, 117.41, 117.812, 116.336, 114.861, 115.392, // 440 nm
    115.923, 112.367, 108.811, 109.082, 109.354, 108.578, 107.802, 106.296, // 480 nm
    104.79, 106.239, 107.689, 106.047, 104.405, 104.225, 104.046, 102.023, // 520 nm
    100.0, 98.1671, 96.3342, 96.0611, 95.788, 92.2368, 88.6856, 89.3459, // 560 nm
    90.0062, 89.8026, 89.5991, 88.6489, 87.6987, 85.4936, 83.2886, 83.4939, // 600 nm
    83.6992, 81.863, 80.0268, 80.1207, 80.2146, 81.2462, 82.2778, 80.281, // 640 nm
    78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979, 74.349, 67.9765, // 680 nm
    61.604, 65.7448, 69.8856, 72.4863, 75.087, 69.3398, 63.5927, 55.0054, // 720 nm
    46.4182, 56.6118, 66.8054, 65.0941, 63.3828, 63.8434, 64.304, 61.8779, // 760 nm
    59.4519, 55.7054, 51.959, 54.6998, 57.4406, 58.8765, 60.3125, // 800 nm
];

#[cfg(test)]
mod tests {
    use super::*;

    /// Values of the `.spd`-style test spectrum at 380, 385, …, 780 nm.
    #[rustfmt::skip]
    const MANY: [f64; 81] = [
        0.112926, 0.092288, 0.075438, 0.062683, 0.054255, 0.050308, 0.050913, 0.056061, 0.065656,
        0.079524, 0.097413, 0.118995, 0.143877, 0.171607, 0.201677, 0.233540, 0.266615, 0.300299,
        0.333978, 0.367036, 0.398873, 0.428906, 0.456590, 0.481418, 0.502938, 0.520758, 0.534555,
        0.544078, 0.549162, 0.549727, 0.545797, 0.537514, 0.525162, 0.509207, 0.490340, 0.469511,
        0.447938, 0.427043, 0.408293, 0.392936, 0.381646, 0.374204, 0.369300, 0.364630, 0.357305,
        0.344544, 0.324443, 0.296585, 0.262262, 0.224236, 0.186115, 0.151568, 0.123619, 0.104221,
        0.094157, 0.093211, 0.100499, 0.114800, 0.134824, 0.159369, 0.187380, 0.217948, 0.250274,
        0.283634, 0.317352, 0.350778, 0.383288, 0.414284, 0.443197, 0.469500, 0.492712, 0.512411,
        0.528236, 0.539900, 0.547190, 0.549972, 0.548197, 0.541895, 0.531184, 0.516257, 0.497386,
    ];

    /// The test spectrum as a `.spd` file, with comments.
    fn many_spd() -> String {
        let mut text = String::from("# test spd\n# wavelength value\n");
        for (i, v) in MANY.iter().enumerate() {
            text += &format!("{} {v:.6}\n", 380 + 5 * i);
        }
        text
    }

    /// A sampled spectrum from pairs, unchecked.
    fn sampled(pairs: &[(f64, f64)]) -> Spectrum {
        Spectrum::Sampled(pairs.to_vec())
    }

    /// Constants and pairs, with Mitsuba's separators.
    #[test]
    fn parses_values() {
        assert_eq!(parse_value("0.5"), Ok(Spectrum::Constant(0.5)));
        assert_eq!(parse_value("  -2e1 "), Ok(Spectrum::Constant(-20.0)));
        let ramp = sampled(&[(400.0, 0.1), (700.0, 0.9)]);
        assert_eq!(parse_value("400:0.1, 700:0.9"), Ok(ramp.clone()));
        assert_eq!(parse_value("400:0.1 700:0.9"), Ok(ramp.clone()));
        assert_eq!(parse_value("4e2:.1,,\n 7.0e2:0.9,"), Ok(ramp));
    }

    /// Malformed `value`s give short errors.
    #[test]
    fn rejects_bad_values() {
        let err = |t: &str| parse_value(t).unwrap_err();
        assert_eq!(err(""), "empty spectrum");
        assert_eq!(err(" , "), "empty spectrum");
        assert_eq!(err("abc"), "'abc' is not a number");
        assert_eq!(err("nan"), "'nan' is not a finite number");
        assert_eq!(err("400:inf, 500:1"), "'inf' is not a finite number");
        assert_eq!(err("0.5 0.6"), "'0.5' is not a wavelength:value pair");
        assert_eq!(
            err("400 : 0.1, 700:0.9"),
            "'400' is not a wavelength:value pair"
        );
        assert_eq!(
            err("400:1:2, 500:1"),
            "'400:1:2' is not a wavelength:value pair"
        );
        assert_eq!(err("400:, 500:1"), "'400:' is not a wavelength:value pair");
        assert_eq!(err("400:x, 500:1"), "'x' is not a number");
        assert_eq!(
            err("500:0.5"),
            "a spectrum needs at least two wavelength:value samples"
        );
        assert_eq!(
            err("600:1, 500:2"),
            "wavelengths must increase: 500 after 600"
        );
        assert_eq!(
            err("500:1, 500:2"),
            "wavelengths must increase: 500 after 500"
        );
        let long = "x".repeat(1000);
        assert!(err(&long).chars().count() < 70);
    }

    /// `.spd` files with comments, CRLF, tabs, commas and extra columns.
    #[test]
    fn parses_spd() {
        let many = parse_spd(many_spd().as_bytes()).unwrap();
        let Spectrum::Sampled(samples) = &many else {
            panic!("not sampled")
        };
        assert_eq!(samples.len(), 81);
        assert_eq!(samples[80], (780.0, 0.497386));
        let ramp = Ok(sampled(&[(400.0, 0.1), (700.0, 0.9)]));
        for text in [
            "400 0.1\r\n700 0.9\r\n",
            "  400\t0.1 # comment\n\n   \n  # indented comment\n700,0.9",
            "400 0.1 5 extra\n700 0.9 6\n",
        ] {
            assert_eq!(parse_spd(text.as_bytes()), ramp, "{text:?}");
        }
    }

    /// Malformed `.spd` files give errors that name the line.
    #[test]
    fn rejects_bad_spd() {
        let err = |t: &[u8]| parse_spd(t).unwrap_err();
        assert_eq!(err(b""), "empty spectrum");
        assert_eq!(err(b"# only a comment\n"), "empty spectrum");
        assert_eq!(
            err(b"400 0.1\n700\n"),
            "line 2: expected 'wavelength value', found only '700'"
        );
        assert_eq!(
            err(b"400 0.1abc\n700 1\n"),
            "line 1: '0.1abc' is not a number"
        );
        assert_eq!(
            err(b"400 0.1\n\xff\xfe 1\n"),
            "line 2: '\u{fffd}\u{fffd}' is not a number"
        );
        assert_eq!(
            err(b"700 0.1\n400 1\n"),
            "wavelengths must increase: 400 after 700"
        );
        assert_eq!(
            err(b"700 0.1\n"),
            "a spectrum needs at least two wavelength:value samples"
        );
    }

    /// A constant reflectance is grey; a constant emission is the equal-energy colour.
    #[test]
    fn constants_as_mitsuba() {
        for v in [0.0, 0.5, 1.7, -0.5] {
            let c = convert(&Spectrum::Constant(v), SpectrumUse::Reflectance);
            assert_eq!(
                c,
                Conversion {
                    rgb: DVec3::splat(v),
                    clamped_from: None
                }
            );
        }
        // Emitters: v times the equal-energy colour, unclamped even when negative.
        let e = convert(&Spectrum::Constant(-1.0), SpectrumUse::Emission);
        assert!(e.clamped_from.is_none());
        assert!(
            (e.rgb - DVec3::new(-1.204794, -0.948291, -0.908916))
                .abs()
                .max_element()
                < 1e-6
        );
    }

    /// Shorthand for a reflectance.
    const R: SpectrumUse = SpectrumUse::Reflectance;
    /// Shorthand for an emission.
    const E: SpectrumUse = SpectrumUse::Emission;

    /// Mitsuba 3.9.1 (`pip install mitsuba`), `scalar_rgb` and `llvm_ad_rgb` alike: the
    /// value of `reflectance.value` of a `diffuse` BSDF or of `intensity.value` of a `point`
    /// emitter after `mi.load_string` of `<spectrum name=… value=…/>` (or `filename=`), read
    /// with `mi.traverse` (single precision, printed with 9 digits). `area`, `directional` and
    /// `constant` emitters gave the same numbers as `point`.
    #[rustfmt::skip]
    const MITSUBA: &[(&str, SpectrumUse, [f64; 3])] = &[
        ("400:0.5, 700:0.5", R, [0.497671008, 0.499878198, 0.497454554]),
        ("360:1, 830:1", R, [0.998985291, 0.998873711, 0.998801589]),
        ("400:0.1, 700:0.9", R, [0.742852807, 0.481140077, 0.208324552]),
        ("400:0.34, 500:0.52, 600:0.61, 700:0.7", R, [0.642558038, 0.56200695, 0.41816321]),
        ("540:0, 545:1, 550:0", R, [0.0, 0.0732415393, 0.0]),
        ("300:0.2, 500:0.8, 900:0.4", R, [0.645256758, 0.771802425, 0.650341868]),
        ("spd", R, [0.183448866, 0.525745928, 0.20978269]),
        ("900:1, 1000:1", R, [0.0, 0.0, 0.0]),
        ("400:2, 700:2", R, [1.0, 1.0, 1.0]),
        ("0.5", R, [0.5, 0.5, 0.5]),
        ("1.7", R, [1.70000005, 1.70000005, 1.70000005]),
        ("2", E, [2.40958786, 1.89658201, 1.81783211]),
        ("3", E, [3.61438179, 2.84487295, 2.72674823]),
        ("400:1, 500:5, 600:10, 700:3", E, [11.1462078, 7.01080799, 2.2256465]),
        ("360:1, 830:1", E, [1.20488369, 0.94822818, 0.909266829]),
        ("540:0, 545:1, 550:0", E, [0.0, 0.0695673898, 0.0]),
        ("380:4, 450:8, 480:0.5", E, [0.439481109, 0.0, 5.50486422]),
        ("spd", E, [0.244444817, 0.50076443, 0.180896834]),
        // A conductor's `eta` (D65-weighted, only negatives clipped).
        ("400:0.2, 700:1.5", SpectrumUse::Unbounded, [1.24446106, 0.819343448, 0.375836492]),
    ];

    /// Every entry of [`MITSUBA`] within 1e-6 relative (single-precision rounding).
    #[test]
    fn matches_mitsuba() {
        let mut worst = 0.0f64;
        for &(text, usage, expected) in MITSUBA {
            let spectrum = if text == "spd" {
                parse_spd(many_spd().as_bytes()).unwrap()
            } else {
                parse_value(text).unwrap()
            };
            let got = to_linear_srgb(&spectrum, usage);
            for (g, e) in got.to_array().into_iter().zip(expected) {
                // Mitsuba hands back single precision: allow a few of its ulps.
                let error = (g - e).abs() / e.abs().max(1e-3);
                worst = worst.max(error);
                assert!(
                    error < 1e-6,
                    "{text} {usage:?}: got {got}, Mitsuba {expected:?}"
                );
            }
        }
        eprintln!("worst relative difference from Mitsuba: {worst:.2e}");
    }

    /// Clamping is reported where Mitsuba warns, with the colour it prints.
    #[test]
    fn reports_clamping() {
        let peak = parse_value("540:0, 545:1, 550:0").unwrap();
        let c = convert(&peak, R);
        let before = c.clamped_from.expect("Mitsuba clamps this one");
        // Mitsuba's warning: "clamping out-of-gamut color [-0.0168943, 0.0732415, -0.008129]"
        let mitsuba = DVec3::new(-0.0168943, 0.0732415, -0.008129);
        assert!((before - mitsuba).abs().max_element() < 1e-6, "{before}");
        assert!(
            convert(&parse_value("400:2, 700:2").unwrap(), E)
                .clamped_from
                .is_none()
        );
        assert!(
            convert(&parse_value("400:2, 700:2").unwrap(), R)
                .clamped_from
                .is_some()
        );
        assert!(
            convert(&parse_value("400:0.5, 700:0.5").unwrap(), R)
                .clamped_from
                .is_none()
        );
    }

    /// Invalid hand-built spectra and huge lists do not panic.
    #[test]
    fn never_panics() {
        let odd = [
            Spectrum::Sampled(vec![]),
            sampled(&[(500.0, 1.0)]),
            sampled(&[(500.0, 1.0), (500.0, 2.0)]),
            sampled(&[(700.0, 1.0), (400.0, 2.0), (600.0, 3.0)]),
            sampled(&[(f64::NAN, 1.0), (600.0, f64::INFINITY)]),
            sampled(&[(-1e300, 1.0), (1e300, 1.0)]),
            Spectrum::Constant(f64::NAN),
        ];
        for s in &odd {
            for usage in [R, E] {
                let _ = convert(s, usage);
            }
        }
        // A huge, dense list: still quick, and a flat 1 over the full range is white.
        let dense: Vec<(f64, f64)> = (0..200_000)
            .map(|i| (300.0 + i as f64 * 0.003, 1.0))
            .collect();
        let white = to_linear_srgb(&Spectrum::Sampled(dense), R);
        assert!((white - DVec3::ONE).abs().max_element() < 2e-3, "{white}");
        assert!(parse_value(&"400:0.5, ".repeat(3)).is_err());
    }
}
