//! The rough plastic coating's tables (`shared::material::rough_plastic_transmittance`), as
//! Mitsuba 3's `roughplastic` computes them in `parameters_changed` with `eval_transmittance`
//! and `eval_reflectance`: the rough dielectric interface's directional transmittance t(μ) for
//! light arriving from outside at the 64 cosines μ_k = max(k/63, 10⁻⁶), and its internal
//! reflectance R_int = 2·mean_k(R(μ_k, 1/η)·μ_k). Each is a Gauss–Legendre quadrature over the
//! unit square of GGX visible-normal samples (32² nodes for η > 1, 128² below), in f64 here and
//! rounded once.
use shared::layout::Material;
use shared::material::{ROUGH_PLASTIC_TABLE_RES, ROUGH_PLASTIC_TABLE_WORDS};

/// A rough coating's transmittance at the table's cosines and its internal reflectance.
#[derive(Clone, Debug, PartialEq)]
pub struct CoatingTable {
    pub transmittance: Vec<f64>,
    pub internal_reflectance: f64,
}

/// The `n`-point Gauss–Legendre nodes and weights on [−1, 1] (Newton's method on Pₙ).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0f64, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            if n == 1 {
                p0 = 1.0;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let step = p1 / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out.reverse();
    out
}

type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: V) -> V {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// Mitsuba's GGX visible-normal sample for `w` in the xz-plane (w_y = 0, w_z > 0): stretch,
/// sample the unit-roughness slopes (`sample_visible_11`), unstretch.
fn sample_visible(alpha: f64, w: V, u: [f64; 2]) -> V {
    let ws = normalize([alpha * w[0], alpha * w[1], w[2]]);
    let cos_theta = ws[2];
    // The concentric disk (Shirley–Chiu), as Mitsuba's `square_to_uniform_disk_concentric`.
    let (x, y) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
    let (px, py) = if x == 0.0 && y == 0.0 {
        (0.0, 0.0)
    } else if x.abs() > y.abs() {
        let phi = std::f64::consts::FRAC_PI_4 * (y / x);
        (x * phi.cos(), x * phi.sin())
    } else {
        let phi = std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (x / y);
        (y * phi.cos(), y * phi.sin())
    };
    let s = 0.5 * (1.0 + cos_theta);
    let h = (1.0 - px * px).max(0.0).sqrt();
    let py = h * (1.0 - s) + py * s;
    let pz = (1.0 - px * px - py * py).max(0.0).sqrt();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let norm = 1.0 / (sin_theta * py + cos_theta * pz);
    let (sx, sy) = ((cos_theta * py - sin_theta * pz) * norm, px * norm);
    // ws lies in the xz-plane with ws_x ≥ 0: the rotation by its azimuth is the identity.
    normalize([-sx * alpha, -sy * alpha, 1.0])
}

/// Smith's G1 for either side (Mitsuba's `smith_g1`): 0 where w sees the other side of m.
fn g1(alpha: f64, w: V, m: V) -> f64 {
    if dot(w, m) * w[2] <= 0.0 {
        return 0.0;
    }
    let z2 = w[2] * w[2];
    let tan2 = (1.0 - z2).max(0.0) / z2;
    2.0 / (1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// Mitsuba's `fresnel`: reflectance, the signed refracted cosine and 1/η for the direction.
fn fresnel(cos_i: f64, eta: f64) -> (f64, f64, f64) {
    let (eta_it, cos_i_abs) = if cos_i >= 0.0 { (eta, cos_i) } else { (1.0 / eta, -cos_i) };
    let eta_ti = 1.0 / eta_it;
    let cos_t2 = 1.0 - (1.0 - cos_i_abs * cos_i_abs) * eta_ti * eta_ti;
    if cos_t2 <= 0.0 {
        return (1.0, 0.0, eta_ti);
    }
    let cos_t = cos_t2.sqrt();
    let rs = (cos_i_abs - eta_it * cos_t) / (cos_i_abs + eta_it * cos_t);
    let rp = (eta_it * cos_i_abs - cos_t) / (eta_it * cos_i_abs + cos_t);
    let signed = if cos_i >= 0.0 { -cos_t } else { cos_t };
    (0.5 * (rs * rs + rp * rp), signed, eta_ti)
}

/// The table's cosines, as Mitsuba's `max(1e-6, linspace(0, 1, 64))`.
pub fn table_cosines() -> Vec<f64> {
    let n = ROUGH_PLASTIC_TABLE_RES as usize;
    (0..n).map(|k| (k as f64 / (n - 1) as f64).max(1e-6)).collect()
}

/// The rough interface's directional transmittance (`refract`: true) or reflectance for light
/// arriving at cosine `mu` from the side of relative index `eta` (Mitsuba's
/// `eval_transmittance`, `eval_reflectance`).
pub fn directional(alpha: f64, eta: f64, mu: f64, refract: bool) -> f64 {
    let res = if eta > 1.0 { 32 } else { 128 };
    let nodes = gauss_legendre(res);
    let w = [(1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu];
    let mut sum = 0.0;
    for &(ny, wy) in &nodes {
        for &(nx, wx) in &nodes {
            let m = sample_visible(alpha, w, [0.5 * nx + 0.5, 0.5 * ny + 0.5]);
            let cos_m = dot(w, m);
            let (f, cos_t, eta_ti) = fresnel(cos_m, eta);
            let value = if refract {
                let k = cos_m * eta_ti + cos_t;
                let o = [m[0] * k - w[0] * eta_ti, m[1] * k - w[1] * eta_ti, m[2] * k - w[2] * eta_ti];
                if o[2] * w[2] >= 0.0 {
                    0.0
                } else {
                    g1(alpha, o, m) * (1.0 - f)
                }
            } else {
                let o = [2.0 * cos_m * m[0] - w[0], 2.0 * cos_m * m[1] - w[1], 2.0 * cos_m * m[2] - w[2]];
                if o[2] <= 0.0 || w[2] <= 0.0 {
                    0.0
                } else {
                    g1(alpha, o, m) * f
                }
            };
            sum += value * wx * wy * 0.25;
        }
    }
    sum
}

impl CoatingTable {
    /// The tables of a coating of GGX `alpha` and index `eta` (outside 1).
    pub fn new(alpha: f32, eta: f32) -> Self {
        let (alpha, eta) = (alpha as f64, eta as f64);
        let mus = table_cosines();
        let transmittance = mus.iter().map(|&mu| directional(alpha, eta, mu, true)).collect();
        let internal: f64 = mus.iter().map(|&mu| directional(alpha, 1.0 / eta, mu, false) * mu).sum();
        Self { transmittance, internal_reflectance: 2.0 * internal / mus.len() as f64 }
    }

    /// The base's constant factors (`Material::params.z`, `.w`): 1 / (η²(1 − R_int)) over π and
    /// as it is, each rounded once.
    pub fn scale(&self, eta: f32) -> (f32, f32) {
        let eta = eta as f64;
        let k = 1.0 / (eta * eta * (1.0 - self.internal_reflectance));
        ((k / std::f64::consts::PI) as f32, k as f32)
    }

    /// The table's words for the texture buffer: per interval its start value and its step
    /// (each rounded once from the f32 values), then (t(1), 0).
    pub fn words(&self) -> Vec<u32> {
        let t: Vec<f32> = self.transmittance.iter().map(|&v| v as f32).collect();
        let mut out = Vec::with_capacity(ROUGH_PLASTIC_TABLE_WORDS as usize);
        for k in 0..t.len() {
            let step = if k + 1 < t.len() { t[k + 1] - t[k] } else { 0.0 };
            out.push(t[k].to_bits());
            out.push(step.to_bits());
        }
        out
    }
}

/// Appends the table of every rough plastic in `materials` to the texture buffer `words` and
/// points the material's `table` at it (one table for materials of the same α and η); a smooth
/// or other material gets 0. Deterministic: a compiled scene's tables are the same again.
pub fn append_tables(materials: &mut [Material], words: &mut Vec<u32>) {
    let mut made: Vec<((u32, u32), u32)> = Vec::new();
    for m in materials.iter_mut() {
        m.table = 0;
        if m.kind == shared::layout::MATERIAL_PLASTIC && m.params.x > 0.0 {
            let key = (m.params.x.to_bits(), m.params.y.to_bits());
            m.table = match made.iter().find(|(k, _)| *k == key) {
                Some(&(_, at)) => at,
                None => {
                    let at = words.len() as u32;
                    words.extend(CoatingTable::new(m.params.x, m.params.y).words());
                    made.push((key, at));
                    at
                }
            };
        }
    }
}
