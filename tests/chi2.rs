//! χ² goodness-of-fit tests of every sampling routine in `shared::sampling` and
//! `shared::material`, after Mitsuba 3's `mitsuba.chi2` (python/mitsuba/chi2.py, itself after
//! Mitsuba 0.5's chi2test): draw many samples, histogram them over a 2-D parameterisation of the
//! domain, integrate the claimed pdf over every bin numerically to get the expected counts, pool
//! the bins whose expected count is below 5, and compare with Pearson's χ² statistic. A bin with
//! observations but no expected mass fails outright, and the pdf must integrate to 1 over the
//! domain (to 1e-3), so a pdf that is wrong only in its normalisation is caught too.
//!
//! There are `TESTS` χ² tests in this file, each at the Šidák level 1 − (1 − α)^(1/TESTS) with
//! α = 0.01, so the chance that a correct sampler fails any of them is 1%. The random numbers come
//! from a fixed-seed PCG, so the outcome is deterministic. Every test also runs the same
//! comparison against a deliberately wrong pdf and asserts that it is rejected, which shows that
//! the test has the power to fail.
use kdtrace::scene::{conductor, diffuse, Scene};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use shared::{
    features::Variant,
    glam::{Vec3, Vec4},
    layout::{Light, Triangle},
    material::{eval, sample},
    rng::{Sampler, SAMPLER_INDEPENDENT, SAMPLER_SOBOL},
    sampling::{cosine_hemisphere, remap_in_light, select_light, uniform_triangle},
    vecmath::luminance,
};
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;

const ALPHA: f64 = 0.01;
/// χ² tests of correct samplers in this file (the deliberately wrong pdfs are not counted: they
/// must fail and are not part of the family whose false-alarm rate is controlled).
const TESTS: u64 = 43;
const MIN_EXPECTED: f64 = 5.0;
const SAMPLES: usize = 1_000_000;

/// Šidák's per-test level for `TESTS` tests at family-wise level `ALPHA`.
fn level() -> f64 {
    kdtrace::image::metrics::sidak_alpha(ALPHA, TESTS)
}

#[derive(Debug)]
struct Chi2 {
    statistic: f64,
    dof: u64,
    p: f64,
    pooled_bins: usize,
    /// Why the test failed before χ² (mass outside the pdf's support, bad normalisation).
    failure: Option<String>,
}

impl Chi2 {
    fn rejected(&self) -> bool {
        self.failure.is_some() || self.p < level()
    }
}

/// Pearson's χ² of `observed` against `expected` counts (same total), with Mitsuba's pooling:
/// cells sorted by expected count, those below `MIN_EXPECTED` merged into one pooled cell (which
/// keeps absorbing cells until it reaches `MIN_EXPECTED`).
fn chi2(observed: &[f64], expected: &[f64]) -> Chi2 {
    let total_obs: f64 = observed.iter().sum();
    let total_exp: f64 = expected.iter().sum();
    let mut failure = None;
    if (total_exp / total_obs - 1.0).abs() > 1e-3 {
        failure = Some(format!("pdf integrates to {} over the domain, not 1", total_exp / total_obs));
    }
    let mut order: Vec<usize> = (0..observed.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut stat, mut dof) = (0f64, 0u64);
    let (mut pooled_obs, mut pooled_exp, mut pooled_bins) = (0f64, 0f64, 0usize);
    for i in order {
        let (o, e) = (observed[i], expected[i]);
        if e == 0.0 {
            if o > 0.0 && failure.is_none() {
                failure = Some(format!("bin {i}: {o} samples where the pdf is 0"));
            }
        } else if e < MIN_EXPECTED || (pooled_exp > 0.0 && pooled_exp < MIN_EXPECTED) {
            pooled_obs += o;
            pooled_exp += e;
            pooled_bins += 1;
        } else {
            stat += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pooled_exp > 0.0 {
        stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        dof += 1;
    }
    // One degree of freedom is lost to the fixed total.
    let dof = dof.saturating_sub(1).max(1);
    let p = ChiSquared::new(dof as f64).unwrap().sf(stat);
    Chi2 { statistic: stat, dof, p, pooled_bins, failure }
}

/// 5-point Gauss–Legendre nodes and weights on [0, 1].
const GL: [(f64, f64); 5] = [
    (0.046_910_077_030_668, 0.118_463_442_528_095),
    (0.230_765_344_947_158, 0.239_314_335_249_683),
    (0.5, 0.284_444_444_444_444),
    (0.769_234_655_052_842, 0.239_314_335_249_683),
    (0.953_089_922_969_332, 0.118_463_442_528_095),
];

/// Expected counts per bin of an `nx`×`ny` grid over [0,1]²: `samples` × ∫∫_bin density, with
/// `density(x, y)` the pdf in the (x, y) parameterisation (Jacobian included), integrated by
/// 5×5-point Gauss–Legendre in each bin. Bins are laid out so that `density` is smooth inside
/// each (kinks only on bin edges).
fn integrate_bins(nx: usize, ny: usize, samples: usize, density: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    let mut out = vec![0f64; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let mut s = 0.0;
            for (a, wa) in GL {
                for (b, wb) in GL {
                    s += wa * wb * density((i as f64 + a) / nx as f64, (j as f64 + b) / ny as f64);
                }
            }
            out[j * nx + i] = s / (nx * ny) as f64 * samples as f64;
        }
    }
    out
}

/// Mitsuba's `SphericalDomain`: (x, y) ∈ [0,1]² ↔ (cos θ = 2x − 1, φ = 2π y); dω = 4π dx dy.
fn sphere_point(x: f64, y: f64) -> Vec3 {
    let z = 2.0 * x - 1.0;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * y;
    Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)
}

fn sphere_bin(w: Vec3, nx: usize, ny: usize) -> usize {
    let w = w.as_dvec3().normalize();
    let x = ((w.z.clamp(-1.0, 1.0) + 1.0) / 2.0 * nx as f64).min(nx as f64 - 1.0) as usize;
    let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
    let y = (phi / (2.0 * PI) * ny as f64).min(ny as f64 - 1.0) as usize;
    y * nx + x
}

/// χ² of directions from `draw` against the solid-angle pdf `pdf`, over (cos θ, φ) bins.
fn spherical_chi2(draw: &mut dyn FnMut(f32, f32) -> Vec3, pdf: &dyn Fn(Vec3) -> f64, seed: u64) -> Chi2 {
    // An even number of cos θ bins puts the hemisphere boundary on a bin edge.
    let (nx, ny) = (20, 40);
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut obs = vec![0f64; nx * ny];
    for _ in 0..SAMPLES {
        let w = draw(rng.random(), rng.random());
        obs[sphere_bin(w, nx, ny)] += 1.0;
    }
    let exp = integrate_bins(nx, ny, SAMPLES, |x, y| pdf(sphere_point(x, y)) * 4.0 * PI);
    chi2(&obs, &exp)
}

fn assert_pass_and_wrong_rejected(name: &str, good: Chi2, wrong: Chi2) {
    eprintln!("{name}: {good:?}\n{name} against a wrong pdf: {wrong:?}");
    assert!(!good.rejected(), "{name}: rejected at level {}: {good:?}", level());
    assert!(wrong.rejected(), "{name}: the wrong pdf was not rejected: {wrong:?}");
}

#[test]
fn cosine_hemisphere_follows_cos_theta_over_pi() {
    let cos_pdf = |w: Vec3| (w.z as f64).max(0.0) / PI;
    let good = spherical_chi2(&mut |u1, u2| cosine_hemisphere(u1, u2), &cos_pdf, 1);
    // Wrong: the uniform hemisphere, 1/(2π), which also integrates to 1.
    let wrong =
        spherical_chi2(&mut |u1, u2| cosine_hemisphere(u1, u2), &|w: Vec3| if w.z > 0.0 { 0.5 / PI } else { 0.0 }, 1);
    assert_pass_and_wrong_rejected("cosine hemisphere", good, wrong);
    // Subtly wrong: tilted by 3% toward +x, (cos θ/π)(1 + 0.03 sin θ cos φ), still normalised.
    let tilted = |w: Vec3| cos_pdf(w) * (1.0 + 0.03 * w.x as f64);
    let good = spherical_chi2(&mut |u1, u2| cosine_hemisphere(u1, u2), &cos_pdf, 2);
    let wrong = spherical_chi2(&mut |u1, u2| cosine_hemisphere(u1, u2), &tilted, 2);
    assert_pass_and_wrong_rejected("cosine hemisphere (3% tilt)", good, wrong);
}

/// The Lambertian BSDF's `sample` about several normals: its directions follow the pdf that
/// `eval` reports, and the pdf it returns with each sample is that same pdf.
#[test]
fn lambertian_sample_directions_follow_its_pdf_about_any_normal() {
    let m = diffuse(Vec3::new(0.8, 0.5, 0.2), Vec3::ZERO);
    let normals = [Vec3::Z, Vec3::new(0.3, -0.5, 0.81).normalize(), Vec3::new(-1e-4, 1e-4, -1.0).normalize()];
    for (k, &n) in normals.iter().enumerate() {
        let mut worst_pdf_mismatch = 0f64;
        let mut draw = |u1: f32, u2: f32| {
            let s = sample(Variant::GENERIC_SPEC, &m, &[], n, n, true, u1, u2, 0.5);
            let (f, pdf) = eval(Variant::GENERIC_SPEC, &m, &[], n, n, s.wi, true);
            if s.pdf > 1e-3 {
                worst_pdf_mismatch = worst_pdf_mismatch.max((s.pdf as f64 / pdf as f64 - 1.0).abs());
                // weight = f·cos/pdf = albedo.
                let cos = n.dot(s.wi);
                assert!(((f.x * cos / s.pdf) - s.weight.x).abs() < 1e-3 * s.weight.x, "weight {:?}", s.weight);
            }
            s.wi
        };
        let pdf = |w: Vec3| eval(Variant::GENERIC_SPEC, &m, &[], n, n, w.normalize(), true).1 as f64;
        let good = spherical_chi2(&mut draw, &pdf, 10 + k as u64);
        assert!(worst_pdf_mismatch < 1e-3, "normal {n:?}: sample's pdf differs from eval's by {worst_pdf_mismatch}");
        // Wrong: cos²θ·3/(2π) about the normal, normalised but too peaked.
        let wrong_pdf = |w: Vec3| {
            let c = n.dot(w.normalize()) as f64;
            if c > 0.0 {
                1.5 * c * c / PI
            } else {
                0.0
            }
        };
        let wrong = spherical_chi2(
            &mut |u1, u2| sample(Variant::GENERIC_SPEC, &m, &[], n, n, true, u1, u2, 0.5).wi,
            &wrong_pdf,
            10 + k as u64,
        );
        assert_pass_and_wrong_rejected(&format!("Lambertian about {n:?}"), good, wrong);
    }
}

/// `spherical_chi2` for samplers that may return no direction (a reflection below the surface)
/// and peaked pdfs: each of the 40×80 bins integrated over 3×3 sub-bins, and the lost samples in
/// a cell of their own whose expected count is the mass the pdf leaves outside the sphere's bins.
fn lossy_spherical_chi2(draw: &mut dyn FnMut(f32, f32) -> Option<Vec3>, pdf: &dyn Fn(Vec3) -> f64, seed: u64) -> Chi2 {
    let (nx, ny, sub) = (40, 80, 3);
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut obs = vec![0f64; nx * ny + 1];
    for _ in 0..SAMPLES {
        match draw(rng.random(), rng.random()) {
            Some(w) => obs[sphere_bin(w, nx, ny)] += 1.0,
            None => obs[nx * ny] += 1.0,
        }
    }
    let fine = integrate_bins(nx * sub, ny * sub, SAMPLES, |x, y| pdf(sphere_point(x, y)) * 4.0 * PI);
    let mut exp = vec![0f64; nx * ny + 1];
    for j in 0..ny * sub {
        for i in 0..nx * sub {
            exp[(j / sub) * nx + i / sub] += fine[j * nx * sub + i];
        }
    }
    exp[nx * ny] = (SAMPLES as f64 - exp.iter().sum::<f64>()).max(0.0);
    chi2(&obs, &exp)
}

/// The rough conductor (GGX, visible normals): at α 0.2, 0.5 and 1 and incident angles of 0°,
/// 45° and 75°, its directions follow the pdf `eval` reports, `sample` returns that pdf and the
/// weight f·cos/pdf; the same test rejects the pdf of a 15% larger α.
#[test]
fn rough_conductor_samples_follow_its_pdf() {
    let n = Vec3::new(0.2, -0.3, 0.9).normalize();
    let (t, b) = shared::sampling::orthonormal_basis(n);
    let gold =
        |alpha: f32| conductor(Vec3::new(0.143, 0.375, 1.442), Vec3::new(3.983, 2.386, 1.603), alpha, Vec3::ZERO);
    let v = Variant::GENERIC_SPEC;
    let mut k = 0;
    for alpha in [0.2f32, 0.5, 1.0] {
        for theta in [0.0f32, 45.0, 75.0] {
            let th = theta.to_radians();
            let wo = (t * th.sin() + n * th.cos()).normalize();
            let m = gold(alpha);
            let mut worst = 0f64;
            let mut draw = |u1: f32, u2: f32| {
                let s = sample(v, &m, &[], n, wo, true, u1, u2, 0.5);
                if s.pdf <= 0.0 {
                    return None;
                }
                let (f, pdf) = eval(v, &m, &[], n, wo, s.wi, true);
                let e1 = (s.pdf as f64 / pdf as f64 - 1.0).abs();
                let w = f * (n.dot(s.wi) / s.pdf);
                // Relative, but absolute below 1e-3: at grazing angles (cos ~ 1e-6) the cosine's
                // rounding in world and local coordinates differs by more than the weight.
                let e2 = ((w - s.weight).abs().max_element() / s.weight.max_element().max(1e-3)) as f64;
                worst = worst.max(e1).max(e2);
                Some(s.wi)
            };
            let pdf = |w: Vec3| eval(v, &m, &[], n, wo, w.normalize(), true).1 as f64;
            let good = lossy_spherical_chi2(&mut draw, &pdf, 100 + k);
            assert!(worst < 2e-3, "α {alpha}, θ {theta}: sample's pdf or weight differs from eval's by {worst}");
            let wide = gold(alpha * 1.15);
            let wrong_pdf = |w: Vec3| eval(v, &wide, &[], n, wo, w.normalize(), true).1 as f64;
            let wrong = lossy_spherical_chi2(
                &mut |u1, u2| Some(sample(v, &m, &[], n, wo, true, u1, u2, 0.5)).filter(|s| s.pdf > 0.0).map(|s| s.wi),
                &wrong_pdf,
                100 + k,
            );
            assert_pass_and_wrong_rejected(&format!("rough conductor α {alpha}, θ {theta}°"), good, wrong);
            k += 1;
        }
    }
    let _ = b;
}

/// Area of the part of the bin [x0, x1]×[y0, y1] below the diagonal x + y ≤ 1, exactly: the
/// covered height clamp(1 − x − y0, 0, y1 − y0) is piecewise linear in x with kinks at 1 − y1
/// and 1 − y0, so the trapezoid rule on the pieces is exact.
fn area_below_diagonal(x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let h = |x: f64| (1.0 - x - y0).clamp(0.0, y1 - y0);
    let mut xs = vec![x0, x1];
    xs.extend([1.0 - y1, 1.0 - y0].into_iter().filter(|&k| k > x0 && k < x1));
    xs.sort_by(f64::total_cmp);
    xs.windows(2).map(|w| 0.5 * (w[1] - w[0]) * (h(w[0]) + h(w[1]))).sum()
}

/// χ² of barycentrics (b1, b2) from `uniform_triangle` over a grid on [0,1]², against the
/// expected count `samples` × (weight of the bin's part inside the triangle).
fn triangle_chi2(weight: &dyn Fn(f64, f64, f64, f64) -> f64, seed: u64) -> Chi2 {
    let n = 24;
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut obs = vec![0f64; n * n];
    for _ in 0..SAMPLES {
        let (b0, b1, b2) = uniform_triangle(rng.random(), rng.random());
        assert!(b0 >= 0.0 && b1 >= 0.0 && b2 >= 0.0 && (b0 + b1 + b2 - 1.0).abs() < 1e-6);
        let i = ((b1 as f64 * n as f64) as usize).min(n - 1);
        let j = ((b2 as f64 * n as f64) as usize).min(n - 1);
        obs[j * n + i] += 1.0;
    }
    let mut exp = vec![0f64; n * n];
    for j in 0..n {
        for i in 0..n {
            let (x0, x1, y0, y1) =
                (i as f64 / n as f64, (i + 1) as f64 / n as f64, j as f64 / n as f64, (j + 1) as f64 / n as f64);
            exp[j * n + i] = weight(x0, x1, y0, y1) * SAMPLES as f64;
        }
    }
    chi2(&obs, &exp)
}

#[test]
fn uniform_triangle_is_uniform_in_area_over_barycentric_bins() {
    // Uniform in area = uniform in (b1, b2) over the half square: density 2.
    let good = triangle_chi2(&|x0, x1, y0, y1| 2.0 * area_below_diagonal(x0, x1, y0, y1), 3);
    // Wrong: density 2·(0.8 + 0.6·b1) (integrates to 1 over the triangle: ∫b1 = 1/6), i.e. a
    // triangle sampler with 30% more points on one side than the other. Integrated with the
    // mean b1 of the bin's clipped part, approximated by sub-cells.
    let wrong_weight = |x0: f64, x1: f64, y0: f64, y1: f64| {
        let k = 8;
        let mut s = 0.0;
        for a in 0..k {
            for b in 0..k {
                let (sx0, sx1) = (x0 + (x1 - x0) * a as f64 / k as f64, x0 + (x1 - x0) * (a + 1) as f64 / k as f64);
                let (sy0, sy1) = (y0 + (y1 - y0) * b as f64 / k as f64, y0 + (y1 - y0) * (b + 1) as f64 / k as f64);
                s += 2.0 * (0.8 + 0.6 * 0.5 * (sx0 + sx1)) * area_below_diagonal(sx0, sx1, sy0, sy1);
            }
        }
        s
    };
    let wrong = triangle_chi2(&wrong_weight, 3);
    assert_pass_and_wrong_rejected("uniform triangle", good, wrong);
}

fn triangle(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    let v = |p: [f32; 3]| Vec4::new(p[0], p[1], p[2], 0.0);
    Triangle { v0: v(a), v1: v(b), v2: v(c) }
}

/// `select_light` over the light table that `Scene::new` builds for a synthetic scene: emissive
/// triangles of different areas and emissions, a dim one, and non-emissive ones in between. The
/// expected pmf is computed here from first principles (area × luminance of Ke / total).
#[test]
fn light_selection_follows_power_pmf_of_a_synthetic_table() {
    let mut tris = Vec::new();
    let mut mats = Vec::new();
    let mut names = Vec::new();
    let mut expected_power = Vec::new();
    for k in 0..12 {
        let s = 0.2 + 0.35 * k as f32;
        // Right triangle with legs s and 0.5: area s/4.
        tris.push(triangle([0.0, 0.0, k as f32], [s, 0.0, k as f32], [0.0, 0.5, k as f32]));
        let emission = match k % 4 {
            0 => Vec3::ZERO, // not a light
            1 => Vec3::new(5.0, 4.0, 1.0),
            2 => Vec3::new(0.3, 0.3, 0.3),
            _ => Vec3::new(0.01, 20.0, 2.0),
        };
        mats.push(diffuse(Vec3::splat(0.5), emission));
        names.push(format!("m{k}"));
        if emission != Vec3::ZERO {
            expected_power.push(s as f64 / 4.0 * luminance(emission) as f64);
        }
    }
    let material_of = (0..tris.len() as u32).collect();
    let scene = Scene::new(tris, material_of, mats, names).unwrap();
    let lights: Vec<Light> = scene.lights.clone();
    assert_eq!(lights.len(), expected_power.len());
    let total: f64 = expected_power.iter().sum();
    let pmf: Vec<f64> = expected_power.iter().map(|p| p / total).collect();

    let draw = |seed: u64| {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut obs = vec![0f64; lights.len()];
        for _ in 0..SAMPLES {
            obs[select_light(&lights, lights.len() as u32, rng.random()) as usize] += 1.0;
        }
        obs
    };
    let obs = draw(5);
    let good = chi2(&obs, &pmf.iter().map(|p| p * SAMPLES as f64).collect::<Vec<_>>());
    // Wrong: picking by area alone (what a table that ignored emission would do).
    let areas: Vec<f64> = lights.iter().map(|l| l.area as f64).collect();
    let area_sum: f64 = areas.iter().sum();
    let wrong = chi2(&obs, &areas.iter().map(|a| a / area_sum * SAMPLES as f64).collect::<Vec<_>>());
    assert_pass_and_wrong_rejected("light selection", good, wrong);
    // The table's own pmf field agrees with the first-principles pmf.
    for (l, p) in lights.iter().zip(&pmf) {
        assert!((l.pmf as f64 - p).abs() < 1e-6, "pmf {} vs {p}", l.pmf);
    }
}

/// χ² of 2D points over a 32×32 grid on [0,1]² against `density` (integrated per bin).
fn unit_square_chi2(points: &[(f32, f32)], density: &dyn Fn(f64, f64) -> f64) -> Chi2 {
    let n = 32;
    let mut obs = vec![0f64; n * n];
    for &(x, y) in points {
        assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y), "({x}, {y}) outside [0,1)²");
        obs[((y * n as f32) as usize).min(n - 1) * n + ((x * n as f32) as usize).min(n - 1)] += 1.0;
    }
    chi2(&obs, &integrate_bins(n, n, points.len(), density))
}

/// The samplers' points are uniform on [0,1)² in dimension pairs (0, 1) and (1, 2) of a set.
/// Within one pixel Sobol points are stratified, not independent, so each point here comes from
/// a different pixel (independent scrambles), at a spread of sample indices and sets: the χ²
/// assumption of independent draws holds and the test checks each point's distribution.
#[test]
fn sampler_points_are_uniform_across_pixels() {
    for kind in [SAMPLER_SOBOL, SAMPLER_INDEPENDENT] {
        let draws: Vec<[f32; 3]> = (0..SAMPLES as u32).map(|p| Sampler::at(kind, p, p % 1021, p % 13, 4)).collect();
        let uniform = |_: f64, _: f64| 1.0;
        // Wrong: a 10% slope along x, still normalised.
        let sloped = |x: f64, _: f64| 0.95 + 0.1 * x;
        for (pair, (a, b)) in [(0usize, 1usize), (1, 2)].into_iter().enumerate() {
            let pts: Vec<(f32, f32)> = draws.iter().map(|v| (v[a], v[b])).collect();
            let good = unit_square_chi2(&pts, &uniform);
            let wrong = unit_square_chi2(&pts, &sloped);
            assert_pass_and_wrong_rejected(&format!("sampler {kind}, dimensions {pair}"), good, wrong);
        }
    }
}

/// A unit-square lamp made of two triangles, sampled the way the integrator samples lights: one
/// uniform picks the triangle and, rescaled within the picked triangle's share, becomes the
/// first coordinate of the point on it. The points must be uniform over the square.
#[test]
fn light_points_from_a_rescaled_selection_are_uniform_over_a_quad() {
    let tris = [([0.0f32, 0.0], [1.0f32, 0.0], [1.0f32, 1.0]), ([0.0, 0.0], [1.0, 1.0], [0.0, 1.0])];
    let lights =
        [Light { triangle: 0, pmf: 0.5, cdf: 0.5, area: 0.5 }, Light { triangle: 1, pmf: 0.5, cdf: 1.0, area: 0.5 }];
    let mut rng = Pcg64::seed_from_u64(21);
    let pts: Vec<(f32, f32)> = (0..SAMPLES)
        .map(|_| {
            let (u, u2): (f32, f32) = (rng.random(), rng.random());
            let i = select_light(&lights, 2, u);
            let (b0, b1, b2) = uniform_triangle(remap_in_light(&lights, i, u), u2);
            let (a, b, c) = tris[i as usize];
            let p = |k: usize| b0 * a[k] + b1 * b[k] + b2 * c[k];
            (p(0).clamp(0.0, 0.999_999), p(1).clamp(0.0, 0.999_999))
        })
        .collect();
    let good = unit_square_chi2(&pts, &|_, _| 1.0);
    // Wrong: 10% more points on one triangle than the other.
    let wrong = unit_square_chi2(&pts, &|x, y| if x > y { 1.05 } else { 0.95 });
    assert_pass_and_wrong_rejected("lamp of two triangles", good, wrong);
}

/// The χ² machinery itself: pooling keeps every cell's expected count ≥ 5, a bin with samples
/// but no expected mass fails, and a pdf with the wrong total fails.
#[test]
fn chi2_machinery_pools_small_bins_and_catches_support_and_normalisation_errors() {
    let exp = [1.0, 1.0, 2.0, 2.0, 100.0, 94.0];
    let obs = [2.0, 0.0, 2.0, 2.0, 100.0, 94.0];
    let c = chi2(&obs, &exp);
    assert_eq!((c.pooled_bins, c.dof), (4, 2), "{c:?}");
    assert!(c.statistic.abs() < 1e-12 && !c.rejected(), "{c:?}");
    let c = chi2(&[1.0, 99.0, 100.0], &[0.0, 100.0, 100.0]);
    assert!(c.rejected() && c.failure.as_deref().unwrap().contains("pdf is 0"), "{c:?}");
    let c = chi2(&[100.0, 100.0], &[90.0, 90.0]);
    assert!(c.rejected() && c.failure.as_deref().unwrap().contains("integrates"), "{c:?}");
    // Two equally likely bins, 20000 samples: the binomial σ of one count is 70.7. A 3σ excess
    // (p = 0.0027) passes the Šidák level 0.01/12 ≈ 0.00084, a 4σ one (p = 6.3e-5) does not.
    assert!(!chi2(&[10_212.0, 9_788.0], &[10_000.0, 10_000.0]).rejected());
    assert!(chi2(&[10_283.0, 9_717.0], &[10_000.0, 10_000.0]).rejected());
}

/// χ² of a BSDF with a lobe choice (`material::pick`, fed by a third uniform of its own)
/// against its pdf, and of the same draws against the pdf of `wrong`, which must be rejected.
/// Every sample is checked against `eval`: the pdf it reports and its weight f·|cos|/pdf. Delta
/// samples (a plastic's coating) and failed ones fall in the lost cell. `words`: the texture
/// buffer the materials read (a rough plastic's table).
#[allow(clippy::too_many_arguments)]
fn bsdf_chi2(
    name: &str,
    m: &shared::layout::Material,
    wrong: &shared::layout::Material,
    words: &[u32],
    n: Vec3,
    wo: Vec3,
    front: bool,
    seed: u64,
) {
    let v = Variant::GENERIC_SPEC;
    let run = |pdf_of: &shared::layout::Material, worst: &mut f64| {
        let mut u3 = Pcg64::seed_from_u64(seed ^ 0x5eed);
        let mut draw = |u1: f32, u2: f32| {
            let s = sample(v, m, words, n, wo, front, u1, u2, u3.random());
            if s.pdf <= 0.0 || s.pdf == shared::material::DELTA_PDF {
                return None;
            }
            let (f, pdf) = eval(v, m, words, n, wo, s.wi, front);
            let e1 = (s.pdf as f64 / pdf as f64 - 1.0).abs();
            let w = f * (n.dot(s.wi).abs() / s.pdf);
            let e2 = ((w - s.weight).abs().max_element() / s.weight.max_element().max(1e-3)) as f64;
            *worst = worst.max(e1).max(e2);
            Some(s.wi)
        };
        lossy_spherical_chi2(&mut draw, &|w: Vec3| eval(v, pdf_of, words, n, wo, w.normalize(), front).1 as f64, seed)
    };
    let mut worst = 0f64;
    let good = run(m, &mut worst);
    // Refraction recomputes the half vector from the refracted direction, whose f32 rounding
    // reaches a few 1e-3 of the weight where o·h + η i·h nearly cancels.
    assert!(worst < 1e-2, "{name}: sample's pdf or weight differs from eval's by {worst}");
    let bad = run(wrong, &mut 0.0);
    assert_pass_and_wrong_rejected(name, good, bad);
}

/// The rough dielectric (Walter et al., visible normals): reflection and refraction, entering
/// and leaving, at α 0.2 and 0.6; a 15% larger α is rejected.
#[test]
fn rough_dielectric_samples_follow_its_pdf() {
    use kdtrace::scene::dielectric;
    let n = Vec3::new(-0.1, 0.3, 0.95).normalize();
    let t = shared::sampling::orthonormal_basis(n).0;
    let cases = [
        (0.2f32, 0.0f32, true),
        (0.2, 60.0, true),
        (0.6, 30.0, true),
        (0.2, 0.0, false),
        (0.2, 30.0, false),
        (0.6, 30.0, false),
    ];
    for (k, (alpha, theta, front)) in cases.into_iter().enumerate() {
        let th = theta.to_radians();
        let wo = (t * th.sin() + n * th.cos()).normalize();
        bsdf_chi2(
            &format!("rough dielectric α {alpha}, θ {theta}°, front {front}"),
            &dielectric(1.5, alpha, Vec3::ZERO),
            &dielectric(1.5, alpha * 1.15, Vec3::ZERO),
            &[],
            n,
            wo,
            front,
            200 + k as u64,
        );
    }
}

/// Plastic: the base's cosine lobe, whose share of the samples is what the coating leaves
/// (a smooth coating's mirror samples are the lost cell), and a rough coating's GGX lobe with it,
/// at α 0.1 and 0.4; a plastic of another albedo (another share) is rejected.
#[test]
fn plastic_samples_follow_its_pdf() {
    use kdtrace::scene::{coating::CoatingTable, plastic};
    let n = Vec3::Z;
    for (k, theta) in [0.0f32, 60.0, 80.0].into_iter().enumerate() {
        let wo = Vec3::new(theta.to_radians().sin(), 0.0, theta.to_radians().cos());
        for (j, alpha) in [0.1f32, 0.4].into_iter().enumerate() {
            // The table at word 0 of the texture buffer.
            let words = CoatingTable::new(alpha, 1.5).words();
            bsdf_chi2(
                &format!("rough plastic α {alpha}, θ {theta}°"),
                &plastic(Vec3::new(0.6, 0.3, 0.1), 1.5, alpha, Vec3::ZERO),
                &plastic(Vec3::new(0.05, 0.05, 0.05), 1.5, alpha, Vec3::ZERO),
                &words,
                n,
                wo,
                true,
                310 + 10 * k as u64 + j as u64,
            );
        }
        bsdf_chi2(
            &format!("plastic, θ {theta}°"),
            &plastic(Vec3::new(0.6, 0.3, 0.1), 1.5, 0.0, Vec3::ZERO),
            &plastic(Vec3::new(0.05, 0.05, 0.05), 1.5, 0.0, Vec3::ZERO),
            &[],
            n,
            wo,
            true,
            300 + k as u64,
        );
    }
}

/// The glTF metallic-roughness model: a dielectric, a metal and a transmissive mix, each at
/// two angles; a 30% rougher material is rejected. (About +z, so that the horizon is a bin
/// edge: a tilted normal leaves bins that barely reach above it, where a grazing metal sample
/// can land with next to no expected mass.)
#[test]
fn principled_samples_follow_its_pdf() {
    use kdtrace::scene::{principled, Principled};
    let n = Vec3::Z;
    let t = shared::sampling::orthonormal_basis(n).0;
    let make = |metallic: f32, roughness: f32, transmission: f32| {
        let p = Principled { base_color: Vec3::new(0.8, 0.5, 0.3), metallic, roughness, transmission, ior: 1.5 };
        principled(&p, Vec3::ZERO)
    };
    let mut k = 0;
    for (metallic, roughness, transmission) in [(0.0f32, 0.5f32, 0.0f32), (1.0, 0.4, 0.0), (0.3, 0.6, 0.7)] {
        for theta in [30.0f32, 70.0] {
            let th = theta.to_radians();
            let wo = (t * th.sin() + n * th.cos()).normalize();
            bsdf_chi2(
                &format!(
                    "principled metallic {metallic}, roughness {roughness}, transmission {transmission}, θ {theta}°"
                ),
                &make(metallic, roughness, transmission),
                &make(metallic, roughness * 1.3, transmission),
                &[],
                n,
                wo,
                true,
                400 + k,
            );
            k += 1;
        }
    }
}

/// A clear coat (KHR_materials_clearcoat) over the glTF model: a smooth-ish coat over a rough
/// dielectric, a half coat over a metal and a rough coat over a transmissive mix, at two angles
/// and from inside (no coat there); a coat 30% rougher is rejected (from inside, the base).
#[test]
fn clear_coated_principled_samples_follow_its_pdf() {
    use kdtrace::scene::{clearcoat, principled, Principled};
    let n = Vec3::Z;
    let t = shared::sampling::orthonormal_basis(n).0;
    let make = |metallic: f32, roughness: f32, transmission: f32, coat: f32, coat_roughness: f32| {
        let p = Principled { base_color: Vec3::new(0.8, 0.5, 0.3), metallic, roughness, transmission, ior: 1.5 };
        clearcoat(principled(&p, Vec3::ZERO), coat, coat_roughness)
    };
    let mut k = 0;
    for (metallic, roughness, transmission, coat, coat_roughness) in
        [(0.0f32, 0.7f32, 0.0f32, 1.0f32, 0.2f32), (1.0, 0.5, 0.0, 0.5, 0.3), (0.3, 0.6, 0.7, 0.8, 0.5)]
    {
        for (theta, front) in [(20.0f32, true), (75.0, true), (40.0, false)] {
            let th = theta.to_radians();
            let wo = (t * th.sin() + n * th.cos()).normalize();
            let wrong = if front {
                make(metallic, roughness, transmission, coat, coat_roughness * 1.3)
            } else {
                make(metallic, roughness * 1.3, transmission, coat, coat_roughness)
            };
            bsdf_chi2(
                &format!(
                    "principled metallic {metallic}, roughness {roughness}, transmission {transmission}, \
                     coat {coat} (roughness {coat_roughness}), θ {theta}°, front {front}"
                ),
                &make(metallic, roughness, transmission, coat, coat_roughness),
                &wrong,
                &[],
                n,
                wo,
                front,
                450 + k,
            );
            k += 1;
        }
    }
}

/// A small non-uniform environment map (16×8: a gradient, a bright spot, a black band), rotated.
fn test_environment_map(rotate: [f64; 3]) -> kdtrace::scene::EnvironmentMap {
    let (w, h) = (16u32, 8u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let base = 0.2 + 0.1 * x as f32 + 0.05 * y as f32;
            if (x, y) == (5, 2) {
                [40.0, 30.0, 20.0]
            } else if y == 6 {
                [0.0; 3]
            } else {
                [base, 0.5 * base, 1.5 * base]
            }
        })
        .collect();
    kdtrace::scene::EnvironmentMap::new(w, h, texels, 1.5, rotate, "test map".into()).unwrap()
}

/// The environment map's sampling (`shared::environment::sample`) follows the density its `pdf`
/// reports, binned in the map's own (u, v) square (bins at half a cell, so the density is
/// smooth inside each), and the density of the map rotated by 10° more is rejected.
#[test]
fn environment_map_samples_follow_its_pdf() {
    use shared::environment;
    let rotate = [20.0, 30.0, -15.0];
    let map = test_environment_map(rotate);
    let words = map.pack(1.0);
    let to_world = map.to_world();
    let (nx, ny) = (32usize, 16usize);
    let uv_dir = |u: f64, v: f64| -> Vec3 {
        let (theta, phi) = (v * PI, u * 2.0 * PI);
        let local = shared::glam::DVec3::new(phi.sin() * theta.sin(), theta.cos(), -phi.cos() * theta.sin());
        (to_world * local).as_vec3()
    };
    let bin = |w: Vec3| -> usize {
        let l = to_world.transpose() * w.as_dvec3().normalize();
        let u = l.x.atan2(-l.z).rem_euclid(2.0 * PI) / (2.0 * PI);
        let v = l.y.clamp(-1.0, 1.0).acos() / PI;
        let (x, y) = ((u * nx as f64).min(nx as f64 - 1.0) as usize, (v * ny as f64).min(ny as f64 - 1.0) as usize);
        y * nx + x
    };
    let run = |pdf: &dyn Fn(Vec3) -> f64, seed: u64| {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut obs = vec![0f64; nx * ny];
        // pdf() of a sampled direction is the sample's own density, except where rounding puts
        // the direction into the neighbouring cell (a few in a million).
        let mut mismatches = 0;
        for _ in 0..SAMPLES {
            let s = environment::sample(&words, 0, rng.random(), rng.random());
            assert!(s.pdf > 0.0 && (s.wi.length() - 1.0).abs() < 1e-5, "sample {:?} pdf {}", s.wi, s.pdf);
            let p = environment::pdf(&words, 0, s.wi);
            if (p as f64 / s.pdf as f64 - 1.0).abs() > 1e-3 {
                mismatches += 1;
            }
            obs[bin(s.wi)] += 1.0;
        }
        assert!(mismatches < SAMPLES / 10_000, "{mismatches} samples whose pdf() differs from their density");
        let exp = integrate_bins(nx, ny, SAMPLES, |u, v| pdf(uv_dir(u, v)) * 2.0 * PI * PI * (v * PI).sin());
        chi2(&obs, &exp)
    };
    let good = run(&|w| environment::pdf(&words, 0, w) as f64, 90);
    let other = test_environment_map([20.0, 40.0, -15.0]).pack(1.0);
    let wrong = run(&|w| environment::pdf(&other, 0, w) as f64, 90);
    assert_pass_and_wrong_rejected("environment map", good, wrong);
    // The radiance a sample carries is the map's radiance in its direction.
    let mut rng = Pcg64::seed_from_u64(91);
    for _ in 0..1000 {
        let s = environment::sample(&words, 0, rng.random(), rng.random());
        let l = environment::eval(&words, 0, s.wi);
        assert!((l - s.radiance).abs().max_element() <= 1e-3 * (1.0 + l.max_element()), "{l} vs {}", s.radiance);
    }
}
