//! Adaptive sampling (`render::adaptive`): the same budgets and the same image on the CPU and
//! on lavapipe, in both modes; samples go where the noise is; the unbiased mode's image has the
//! fixed-sample image's mean (its per-pixel test against Mitsuba is in `reference_mitsuba.rs`).
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    image::metrics::{two_image_test, PixelStats},
    kdbuild::BuildSettings,
    load,
    render::{cpu, gpu, Compiled, Rendered},
    settings::{Adaptive, AdaptiveMode, RenderSettings},
    Loaded,
};
use paths::repo;

fn no_progress(_: u64, _: u64) {}

/// `scenes/uneven-noise.toml`: a bright corner lit by a lamp the camera cannot see, walls lit
/// only by light that came over a partition.
fn uneven() -> Loaded {
    load(&repo("scenes/uneven-noise.toml"), BuildSettings::default()).unwrap()
}

fn settings(l: &Loaded, width: u32, height: u32, spp: u32, adaptive: Option<Adaptive>) -> RenderSettings {
    let (lo, hi) = l.compiled.world_bounds();
    let s = l.settings.resolve(lo, hi).unwrap();
    RenderSettings { width, height, spp, seed: 3, adaptive, ..s }
}

fn adaptive(threshold: f32, mode: AdaptiveMode) -> Option<Adaptive> {
    Some(Adaptive { threshold, min_spp: 8, mode })
}

fn counts(r: &Rendered) -> &[u32] {
    r.counts.as_deref().expect("an adaptive render has per-pixel counts")
}

#[test]
fn cpu_and_lavapipe_render_the_same_adaptive_image() {
    let l = uneven();
    let g = gpu::Gpu::lavapipe().unwrap();
    for mode in [AdaptiveMode::Pilot, AdaptiveMode::AsYouGo] {
        let s = settings(&l, 16, 12, 64, adaptive(0.1, mode));
        let b = g.render(&l.compiled, &s, &no_progress).unwrap();
        let a = cpu::render(&l.compiled, &s, &no_progress).unwrap();
        let (lo, hi) = (counts(&a).iter().min().unwrap(), counts(&a).iter().max().unwrap());
        assert!(lo < hi, "{mode:?}: every pixel got {lo} samples");
        assert_eq!(counts(&a), counts(&b), "{mode:?}: the devices chose different budgets");
        let bits = |r: &Rendered| r.sum.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
        assert!(bits(&a) == bits(&b), "{mode:?}: the devices' sums differ");
        assert_eq!(a.primary, b.primary);
    }
}

/// The budgets follow the noise: the directly lit floor in the bottom-right corner converges
/// fast, the walls lit over the partition do not. Measured from a fixed-sample render's own
/// variance, the pixels that got the most samples are far noisier than those that got the least.
#[test]
fn samples_go_where_the_noise_is() {
    let l = uneven();
    let (w, h) = (32, 24);
    let r =
        cpu::render(&l.compiled, &settings(&l, w, h, 512, adaptive(0.05, AdaptiveMode::Pilot)), &no_progress).unwrap();
    let fixed = cpu::render(&l.compiled, &settings(&l, w, h, 256, None), &no_progress).unwrap();
    let (mean, var) = (fixed.mean(), fixed.variance());
    let rel = |i: usize| (0..3).map(|k| var[i][k] as f64 / (mean[i][k] as f64).powi(2).max(1e-2)).sum::<f64>();
    let mut order: Vec<usize> = (0..(w * h) as usize).collect();
    order.sort_by_key(|&i| counts(&r)[i]);
    let tenth = order.len() / 10;
    let least = order[..tenth].iter().map(|&i| rel(i)).sum::<f64>() / tenth as f64;
    let most = order[order.len() - tenth..].iter().map(|&i| rel(i)).sum::<f64>() / tenth as f64;
    let (lo, mean_spp, hi) = r.spp_range();
    eprintln!("spp {lo}..{hi}, mean {mean_spp:.1}; relative variance: least-sampled tenth {least:.3}, most {most:.3}");
    assert!(most > 4.0 * least, "relative variance {most} (most samples) vs {least} (fewest)");
    assert!(hi > 4 * lo);
}

/// Unbiased mode: several seeds' adaptive images and fixed-sample images agree pixel by pixel
/// under Welch's t-test, and a 10% brighter lamp is caught.
#[test]
fn unbiased_mode_has_the_fixed_images_mean() {
    let l = uneven();
    let (w, h) = (12, 9);
    let seeds = 1..=12;
    let stats = |c: &Compiled, a: Option<Adaptive>| {
        // Each seed's image is one sample of the pixel's estimator: their mean and variance.
        let images: Vec<Vec<[f32; 3]>> = seeds
            .clone()
            .map(|seed| {
                let s = RenderSettings { seed, ..settings(&l, w, h, 128, a) };
                cpu::render(c, &s, &no_progress).unwrap().mean()
            })
            .collect();
        PixelStats::of_images(w, h, &images).unwrap()
    };
    let pilot = stats(&l.compiled, adaptive(0.05, AdaptiveMode::Pilot));
    let fixed = stats(&l.compiled, None);
    let t = two_image_test(&pilot, &fixed, 0.01).unwrap();
    eprintln!("pilot mode against fixed sampling: {t:?}");
    assert!(t.pass, "{t:?}");
    let mut brighter = uneven().compiled;
    brighter.scene.materials.iter_mut().for_each(|m| m.emission *= 1.1);
    let t = two_image_test(&stats(&brighter, None), &pilot, 0.01).unwrap();
    assert!(!t.pass, "a 10% brighter lamp went unnoticed: {t:?}");
}

/// A time limit scales the pilot's budgets to fit, in proportion: budgets far beyond what the
/// time allows still end in a render, every pixel with its least and the noisy ones with more.
#[test]
fn a_time_limit_keeps_the_budgets_in_proportion() {
    let l = uneven();
    let unlimited = settings(&l, 32, 24, 1 << 16, adaptive(0.001, AdaptiveMode::Pilot));
    let s = RenderSettings { time_limit_s: Some(0.5), ..unlimited };
    let r = cpu::render(&l.compiled, &s, &no_progress).unwrap();
    let (lo, mean, hi) = r.spp_range();
    eprintln!("under 0.5 s: spp {lo}..{hi}, mean {mean:.1}");
    // A threshold of 0.001 asks for millions of samples in the noisiest pixels.
    assert!(hi < 1 << 16 && lo >= 1 && hi > 4 * lo, "spp {lo}..{hi}");
    assert!(r.sum.iter().all(|p| p.is_finite()));
}
