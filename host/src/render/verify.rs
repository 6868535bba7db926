//! CPU ≡ GPU agreement: the design card's promise, measured on any scene.
use crate::render::Rendered;
use serde::Serialize;

/// Relative tolerance per channel for a pixel to count as agreeing.
pub const REL_TOLERANCE: f32 = 1e-3;
/// Pass bounds: share of agreeing pixels and of identical primary hits.
pub const MIN_PIXEL_SHARE: f64 = 0.999;
pub const MIN_PRIMARY_SHARE: f64 = 0.9999;

#[derive(Clone, Debug, Serialize)]
pub struct Agreement {
    pub pixels: u64,
    /// Pixels whose channels all agree within `REL_TOLERANCE` relative.
    pub pixels_within: u64,
    pub pixel_share: f64,
    pub bitwise_identical_pixels: u64,
    /// mean((gpu − cpu)² / (cpu² + 0.01)) over channels.
    pub relmse: f64,
    pub max_rel_diff: f64,
    pub primary_matches: u64,
    pub primary_share: f64,
    /// First pixel (row-major) outside the tolerance, with both values.
    pub first_divergent: Option<Divergence>,
    pub pass: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct Divergence {
    pub x: u32,
    pub y: u32,
    pub cpu: [f32; 3],
    pub gpu: [f32; 3],
}

pub fn agree(a: f32, b: f32) -> bool {
    (a - b).abs() <= REL_TOLERANCE * a.abs().max(b.abs())
}

pub fn compare(cpu: &Rendered, gpu: &Rendered) -> Agreement {
    assert_eq!((cpu.width, cpu.height), (gpu.width, gpu.height), "images of different sizes");
    let (c, g) = (cpu.mean(), gpu.mean());
    let n = c.len() as u64;
    let (mut within, mut identical, mut primary, mut relmse, mut max_rel) = (0u64, 0u64, 0u64, 0f64, 0f64);
    let mut first = None;
    for (i, (pc, pg)) in c.iter().zip(&g).enumerate() {
        let ok = (0..3).all(|k| agree(pc[k], pg[k]));
        within += ok as u64;
        identical += (pc.map(f32::to_bits) == pg.map(f32::to_bits)) as u64;
        primary += (cpu.primary[i] == gpu.primary[i]) as u64;
        for k in 0..3 {
            let (r, x) = (pc[k] as f64, pg[k] as f64);
            relmse += (x - r) * (x - r) / (r * r + 0.01);
            let m = r.abs().max(x.abs());
            if m > 0.0 {
                max_rel = max_rel.max((x - r).abs() / m);
            }
        }
        if !ok && first.is_none() {
            first = Some(Divergence { x: i as u32 % cpu.width, y: i as u32 / cpu.width, cpu: *pc, gpu: *pg });
        }
    }
    let pixel_share = within as f64 / n as f64;
    let primary_share = primary as f64 / n as f64;
    Agreement {
        pixels: n,
        pixels_within: within,
        pixel_share,
        bitwise_identical_pixels: identical,
        relmse: relmse / (3 * n) as f64,
        max_rel_diff: max_rel,
        primary_matches: primary,
        primary_share,
        first_divergent: first,
        pass: pixel_share >= MIN_PIXEL_SHARE && primary_share >= MIN_PRIMARY_SHARE,
    }
}
