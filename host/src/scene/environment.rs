//! Environment maps and punctual lights on the host: reading the map (OpenEXR, Radiance HDR or
//! PFM, linear RGB), its sampling tables (built in f64, rounded once) and the words the integrator reads
//! (`shared::environment`, `shared::punctual`), appended to the texture buffer.
use anyhow::{anyhow, bail, Result};
use shared::glam::{DMat3, DVec3, Vec3};
use shared::layout::{PunctualLight as PunctualLayout, PUNCTUAL_DIRECTIONAL, PUNCTUAL_POINT, PUNCTUAL_SPOT};
use std::path::Path;

/// An equirectangular environment map (Mitsuba 3's `envmap` mapping: `shared::environment`).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    pub width: u32,
    pub height: u32,
    /// Linear RGB radiance, row by row from the top (+Y), before `strength`.
    pub texels: Vec<[f32; 3]>,
    /// Factor on every texel.
    pub strength: f32,
    /// Degrees about X, then Y, then Z (Mitsuba's `to_world` = Rz·Ry·Rx).
    pub rotate: [f64; 3],
    /// The file it was read from.
    pub source: String,
}

impl EnvironmentMap {
    /// Reads a map (`.exr`, `.hdr` or `.pfm`): every texel finite and non-negative.
    pub fn read(path: &Path, strength: f32, rotate: [f64; 3]) -> Result<Self> {
        let (width, height, texels) = crate::image::io::read_linear_image(path)?;
        Self::new(width, height, texels, strength, rotate, path.display().to_string())
    }

    /// A map from texels, checked.
    pub fn new(
        width: u32,
        height: u32,
        texels: Vec<[f32; 3]>,
        strength: f32,
        rotate: [f64; 3],
        source: String,
    ) -> Result<Self> {
        if width == 0 || height == 0 || texels.len() != (width * height) as usize {
            bail!("{source}: environment map of {width}×{height} texels with {} values", texels.len());
        }
        if width > 1 << 14 || height > 1 << 14 {
            bail!("{source}: environment map {width}×{height} is larger than 16384 on a side");
        }
        if let Some((i, t)) = texels.iter().enumerate().find(|(_, t)| t.iter().any(|c| !c.is_finite() || *c < 0.0)) {
            bail!(
                "{source}: texel ({}, {}) is {t:?}: environment radiance must be finite and non-negative",
                i as u32 % width,
                i as u32 / width
            );
        }
        if !(strength.is_finite() && strength >= 0.0) {
            bail!("{source}: strength {strength} must be finite and non-negative");
        }
        if rotate.iter().any(|r| !r.is_finite()) {
            bail!("{source}: rotation {rotate:?} must be finite");
        }
        Ok(Self { width, height, texels, strength, rotate, source })
    }

    /// A map of one constant radiance (tests, furnaces).
    pub fn constant(width: u32, height: u32, radiance: [f32; 3]) -> Self {
        Self::new(width, height, vec![radiance; (width * height) as usize], 1.0, [0.0; 3], "constant".into())
            .expect("a valid constant map")
    }

    /// The rotation from the map's frame to the world: Rz·Ry·Rx of `rotate` (degrees), the
    /// matrix Mitsuba builds for `to_world` from rotations about x, then y, then z.
    pub fn to_world(&self) -> DMat3 {
        let r = self.rotate.map(f64::to_radians);
        DMat3::from_rotation_z(r[2]) * DMat3::from_rotation_y(r[1]) * DMat3::from_rotation_x(r[0])
    }

    fn luminance(&self, x: u32, y: u32) -> f64 {
        let t = self.texels[(y * self.width + x) as usize];
        (0.2126 * t[0] as f64 + 0.7152 * t[1] as f64 + 0.0722 * t[2] as f64) * self.strength as f64
    }

    /// Mean radiance (luminance) over the sphere, f64.
    pub fn mean_luminance(&self) -> f64 {
        let (w, h) = (self.width, self.height);
        let mut sum = 0.0;
        let mut weight = 0.0;
        for y in 0..h {
            // Row y lies at θ = π·y/(H − 1); rows weigh by sin θ (poles by a quarter row).
            let theta =
                if h > 1 { std::f64::consts::PI * y as f64 / (h - 1) as f64 } else { std::f64::consts::FRAC_PI_2 };
            let s = theta.sin().max(if h > 1 { 0.25 * (std::f64::consts::PI / (h - 1) as f64).sin() } else { 1.0 });
            for x in 0..w {
                sum += self.luminance(x, y) * s;
                weight += s;
            }
        }
        sum / weight
    }

    /// The words of `shared::environment` for this map, with selection probability `pmf`.
    pub fn pack(&self, pmf: f32) -> Vec<u32> {
        let (w, h) = (self.width, self.height);
        let mut out = Vec::with_capacity(shared::environment::words(w, h) as usize);
        let m = self.to_world();
        let pi = std::f64::consts::PI;
        let (wf, hf) = (w as f64, h as f64);
        out.extend([w, h, pmf.to_bits(), (((hf - 1.0) / hf) as f32).to_bits()]);
        for r in 0..3 {
            let row = m.row(r);
            out.extend([row.x, row.y, row.z].map(|v| (v as f32).to_bits()));
        }
        out.extend([wf / (2.0 * pi), (hf - 1.0) / pi, hf / pi, 1.0 / wf, 1.0 / hf].map(|v| (v as f32).to_bits()));
        out.extend([std::f32::consts::FRAC_PI_2.to_bits(), 0.5f32.to_bits()]);
        // Cell weights: the mean luminance of the texels bilinear lookups in the cell read,
        // times sin θ at the cell's centre.
        let mut weight = vec![0.0f64; (w * h) as usize];
        for y in 0..h {
            let (r0, r1) = if h > 1 {
                let a = (y as f64 * (h - 1) as f64 / h as f64).floor() as u32;
                let b = (((y + 1) as f64 * (h - 1) as f64 / h as f64).ceil() as u32).min(h - 1);
                (a, b)
            } else {
                (0, 0)
            };
            let sin = (std::f64::consts::PI * (y as f64 + 0.5) / h as f64).sin();
            for x in 0..w {
                let mut sum = 0.0;
                let mut n = 0.0;
                for r in r0..=r1 {
                    for dx in [w - 1, 0, 1] {
                        sum += self.luminance((x + dx) % w, r);
                        n += 1.0;
                    }
                }
                weight[(y * w + x) as usize] = sum / n * sin;
            }
        }
        if weight.iter().all(|&v| v <= 0.0) {
            // A black map: sample by solid angle (its radiance is zero anyway).
            for y in 0..h {
                let sin = (std::f64::consts::PI * (y as f64 + 0.5) / h as f64).sin();
                for x in 0..w {
                    weight[(y * w + x) as usize] = sin;
                }
            }
        }
        let rows: Vec<f64> = (0..h).map(|y| weight[(y * w) as usize..((y + 1) * w) as usize].iter().sum()).collect();
        let total: f64 = rows.iter().sum();
        let cdf = |values: &[f64], sum: f64| -> Vec<u32> {
            let mut run = 0.0;
            let mut c = vec![0.0f32.to_bits()];
            for (i, v) in values.iter().enumerate() {
                run += v;
                let x = if i + 1 == values.len() { 1.0 } else { (run / sum) as f32 };
                c.push(x.to_bits());
            }
            c
        };
        out.extend(cdf(&rows, total));
        for y in 0..h {
            let row = &weight[(y * w) as usize..((y + 1) * w) as usize];
            if rows[y as usize] > 0.0 {
                out.extend(cdf(row, rows[y as usize]));
            } else {
                out.extend((0..=w).map(|x| (x as f32 / w as f32).to_bits()));
            }
        }
        let cells = (w * h) as f64;
        let jacobian = 1.0 / (2.0 * pi * pi);
        out.extend(weight.iter().map(|&v| ((v / total * cells * jacobian) as f32).to_bits()));
        let s = self.strength as f64;
        for t in &self.texels {
            out.extend(t.map(|c| ((c as f64 * s) as f32).to_bits()));
        }
        debug_assert_eq!(out.len(), shared::environment::words(w, h) as usize);
        out
    }
}

/// A point, spot or directional light (glTF `KHR_lights_punctual` units: `intensity` in candela
/// for point and spot lights, lux for directional ones). What scene files' `[[light]]` and the
/// glTF importer fill in; positions in the scene's local frame (`Scene::punctual_lights`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PunctualLight {
    pub kind: u32,
    /// Point and spot lights: where the light is.
    pub position: DVec3,
    /// Spot and directional lights: the direction the light travels (normalised on packing).
    pub direction: DVec3,
    /// Linear RGB colour.
    pub color: Vec3,
    pub intensity: f32,
    /// Spot cone, radians (glTF defaults 0 and π/4).
    pub inner_cone_angle: f32,
    pub outer_cone_angle: f32,
}

impl PunctualLight {
    pub fn point(position: DVec3, color: Vec3, intensity: f32) -> Self {
        Self {
            kind: PUNCTUAL_POINT,
            position,
            direction: DVec3::NEG_Y,
            color,
            intensity,
            inner_cone_angle: 0.0,
            outer_cone_angle: std::f32::consts::FRAC_PI_4,
        }
    }
    pub fn spot(position: DVec3, direction: DVec3, color: Vec3, intensity: f32, inner: f32, outer: f32) -> Self {
        Self {
            kind: PUNCTUAL_SPOT,
            direction,
            inner_cone_angle: inner,
            outer_cone_angle: outer,
            ..Self::point(position, color, intensity)
        }
    }
    pub fn directional(direction: DVec3, color: Vec3, intensity: f32) -> Self {
        Self { kind: PUNCTUAL_DIRECTIONAL, direction, ..Self::point(DVec3::ZERO, color, intensity) }
    }

    /// Checks the values (finite, non-negative, a direction, cone angles in order).
    pub fn check(&self) -> Result<()> {
        let ok = self.position.is_finite()
            && self.direction.is_finite()
            && self.color.is_finite()
            && self.color.min_element() >= 0.0
            && self.intensity.is_finite()
            && self.intensity >= 0.0;
        if !ok {
            bail!("light: position, direction, colour and intensity must be finite, colour and intensity non-negative");
        }
        if self.kind != PUNCTUAL_POINT && self.direction.length() == 0.0 {
            return Err(anyhow!("light: the direction must not be zero"));
        }
        if self.kind == PUNCTUAL_SPOT
            && !(0.0 <= self.inner_cone_angle
                && self.inner_cone_angle < self.outer_cone_angle
                && self.outer_cone_angle <= std::f32::consts::FRAC_PI_2)
        {
            bail!(
                "light: spot cone angles must satisfy 0 ≤ inner ({}) < outer ({}) ≤ 90°",
                self.inner_cone_angle.to_degrees(),
                self.outer_cone_angle.to_degrees()
            );
        }
        Ok(())
    }

    /// The layout the integrator reads.
    pub fn layout(&self) -> PunctualLayout {
        let d = self.direction.normalize_or(DVec3::NEG_Y).as_vec3();
        let i = self.color * self.intensity;
        let (scale, offset) = if self.kind == PUNCTUAL_SPOT {
            let (ci, co) = ((self.inner_cone_angle as f64).cos(), (self.outer_cone_angle as f64).cos());
            let scale = 1.0 / (ci - co).max(0.001);
            (scale as f32, (-co * scale) as f32)
        } else {
            (0.0, 1.0)
        };
        PunctualLayout {
            position: self.position.as_vec3().to_array(),
            kind: self.kind,
            direction: d.to_array(),
            _pad0: 0,
            intensity: i.to_array(),
            _pad1: 0,
            cone_scale: scale,
            cone_offset: offset,
            _pad2: [0; 2],
        }
    }

    /// Power for light selection (pbrt-v4): 4π·I (point), 2π·I·(1 − (cos inner + cos outer)/2)
    /// (spot), π·r²·E (directional, r the scene's bounding-sphere radius); luminance of I or E.
    pub fn power(&self, radius: f64) -> f64 {
        let lum = shared::vecmath::luminance(self.color) as f64 * self.intensity as f64;
        match self.kind {
            PUNCTUAL_POINT => 4.0 * std::f64::consts::PI * lum,
            PUNCTUAL_SPOT => {
                let (ci, co) = ((self.inner_cone_angle as f64).cos(), (self.outer_cone_angle as f64).cos());
                2.0 * std::f64::consts::PI * lum * (1.0 - 0.5 * (ci + co))
            }
            _ => std::f64::consts::PI * radius * radius * lum,
        }
    }
}
