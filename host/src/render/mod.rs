//! Rendering on the host: what both renderers share (the compiled scene, render parameters and
//! the accumulated result), loading a scene into that form (`load`) or from a compiled `.kdc`
//! file (`kdc`), the CPU reference (`cpu`), the wgpu runner of the rust-gpu kernel (`gpu`), the
//! renders driven one pass at a time on either device (`progressive`), the CPU ≡ GPU check
//! (`verify`) and the ray-casting benchmark (`raybench`).
pub mod adaptive;
pub mod blocks;
pub mod cpu;
pub mod features;
pub mod gpu;
pub mod kdc;
pub mod light_pool;
pub mod load;
pub mod memory;
pub mod multi;
pub mod partial;
pub mod progressive;
pub mod raybench;
pub mod verify;

use crate::kdbuild::{BuildSettings, KdTree};
use crate::scene::local_frame::{point_to_local, point_to_world};
use crate::scene::Scene;
use crate::settings::{Aov, RenderSettings, Traversal};
use anyhow::{bail, Result};
use rayon::prelude::*;
use shared::glam::{DVec3, Vec3, Vec4};
use shared::layout::{
    Light, RenderParams, TriBlock, Triangle, AOV_ALBEDO, AOV_COST, AOV_NORMAL, AOV_RADIANCE, BLOCK_WIDTH,
    LIGHT_ENVIRONMENT_BIT, LIGHT_NOT_TRIANGLE, NO_ENVIRONMENT_MAP, TRAVERSAL_FULL_STACK, TRAVERSAL_SHORT_STACK,
    TRAVERSAL_WIDE_BVH,
};
use shared::numerics::MAX_EXTENT;
use shared::scene::SceneView;
use shared::vecmath::{luminance, xyz};

/// A scene ready to render: geometry, materials, lights and its k-d tree.
pub struct Compiled {
    pub scene: Scene,
    /// The k-d tree and its leaf blocks: given (`new`), or built with `kd_settings` when first
    /// asked for (`deferred`): a CPU render on the wide BVH never asks.
    kd: std::sync::OnceLock<KdPart>,
    kd_settings: BuildSettings,
    /// The box the tree is built in (the scene's box; for a `.kdc`, the stored tree's): what
    /// rays are clipped to and a default camera frames.
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    /// The light table padded to at least one entry (GPU buffers cannot be empty): the
    /// scene's emitting triangles, then its environment map and punctual lights, one
    /// distribution by power over all of them (`prepare_emitters`).
    pub lights: Vec<Light>,
    /// Entries of `lights` that are real.
    pub light_count: u32,
    /// The scene's texture buffer, then the environment map's and punctual lights' words.
    pub textures: Vec<u32>,
    /// `RenderParams::environment_map`: 1 + the map's first word in `textures`, or 0.
    pub environment_map: u32,
    /// World position of the scene's coordinate origin (`local_frame`): the scene and its tree
    /// are stored relative to it, cameras are given in world space (f64 both).
    pub origin: DVec3,
    /// Whether a material that triangles use has an alpha mask: the CPU's traversals test hits
    /// against masks only then (`SceneView::alpha_masks`).
    pub alpha_masks: bool,
    /// The CPU path's eight-wide BVH over the same triangles (`crate::bvh`), built when a view
    /// for `TRAVERSAL_WIDE_BVH` first asks for it (a GPU render never does).
    pub wide: std::sync::OnceLock<crate::bvh::WideBvh>,
    /// The CPU lanes' split of the triangles (`crate::bvh::split`), built with the wide BVH for
    /// a render through the lanes (`wide_bvh_and_split`); `None` where none pays or the scene
    /// has alpha masks.
    pub split: std::sync::OnceLock<Option<crate::bvh::split::Split>>,
    /// `features::seen_light_share` for the last camera it was asked about (its parameters
    /// without the connections): a render asks for its features several times (its parameters,
    /// the variant, the report), and each pass of a progressive one again.
    pub(crate) seen_light: std::sync::Mutex<Option<(RenderParams, f64)>>,
}

/// The k-d tree with the triangles of its leaves in blocks of `BLOCK_WIDTH`, for the CPU's SIMD
/// leaf test (`shared::layout::TriBlock`; derived from the tree, never stored).
struct KdPart {
    tree: KdTree,
    blocks: Vec<TriBlock>,
}

impl KdPart {
    fn new(mut tree: KdTree, triangles: &[Triangle]) -> Self {
        // A tree from a .kdc file of an older layout, or built elsewhere, gets the block layout
        // the CPU's leaf test relies on; a fresh build already has it.
        crate::kdbuild::align_leaves(&mut tree);
        let blocks = leaf_blocks(&tree.indices, triangles);
        KdPart { tree, blocks }
    }
}

impl Compiled {
    /// The scene with the k-d tree `tree`, built in its box.
    pub fn new(scene: Scene, tree: KdTree) -> Self {
        let (lo, hi) = (tree.bounds_min, tree.bounds_max);
        let c = Self::with_box(scene, BuildSettings::default(), lo, hi);
        let part = KdPart::new(tree, &c.scene.triangles);
        let _ = c.kd.set(part);
        c
    }

    /// The scene, its k-d tree to be built with `settings` in the scene's box when first asked
    /// for (`tree`).
    pub fn deferred(scene: Scene, settings: BuildSettings) -> Self {
        let (lo, hi) = (scene.bounds_min, scene.bounds_max);
        Self::with_box(scene, settings, lo, hi)
    }

    /// The scene laid out for rendering, no tree yet, in the tree's box [bounds_min, bounds_max]
    /// (which also weighs an environment map in the light table).
    fn with_box(mut scene: Scene, settings: BuildSettings, bounds_min: Vec3, bounds_max: Vec3) -> Self {
        // A rough plastic's coating table, also for a material changed after loading.
        scene.refresh_coating_tables();
        // Shading reads each triangle's unit normal from its `w` components.
        scene.triangles.par_iter_mut().for_each(|t| *t = t.with_unit_normal());
        let alpha_masks = features::uses_alpha_masks(&scene);
        let mut c = Self {
            scene,
            kd: std::sync::OnceLock::new(),
            kd_settings: settings,
            bounds_min,
            bounds_max,
            lights: Vec::new(),
            light_count: 0,
            textures: Vec::new(),
            environment_map: NO_ENVIRONMENT_MAP,
            origin: DVec3::ZERO,
            alpha_masks,
            wide: std::sync::OnceLock::new(),
            split: std::sync::OnceLock::new(),
            seen_light: std::sync::Mutex::new(None),
        };
        c.prepare_emitters();
        c
    }

    fn kd(&self) -> &KdPart {
        self.kd.get_or_init(|| {
            let tree = crate::kdbuild::build(&self.scene.triangles, self.bounds_min, self.bounds_max, self.kd_settings);
            KdPart::new(tree, &self.scene.triangles)
        })
    }

    /// The k-d tree, built on the first call of a `deferred` scene.
    pub fn tree(&self) -> &KdTree {
        &self.kd().tree
    }

    /// The triangles of the tree's leaves in blocks of `BLOCK_WIDTH` (`leaf_blocks`).
    pub fn blocks(&self) -> &[TriBlock] {
        &self.kd().blocks
    }

    /// Whether the k-d tree is built (or was given).
    pub fn has_tree(&self) -> bool {
        self.kd.get().is_some()
    }

    /// The k-d tree, built if it was not.
    pub fn into_tree(self) -> KdTree {
        self.kd();
        self.kd.into_inner().expect("built by kd()").tree
    }

    /// Builds the light table and the words after the textures from the scene's emitters: each
    /// emitting triangle (power: area × luminance of its radiance), the environment map (power
    /// 4π·π·r²·its mean luminance, r the radius of the tree box's bounding sphere, as pbrt-v4
    /// gives infinite lights) and each punctual light (`PunctualLight::power`), picked in
    /// proportion to power. Without an environment map or punctual lights the table is the
    /// scene's own (the same bits as before they existed). Call again after changing them.
    pub fn prepare_emitters(&mut self) {
        let scene = &self.scene;
        let mut textures = scene.textures.clone();
        let mut lights = scene.lights.clone();
        self.environment_map = NO_ENVIRONMENT_MAP;
        if scene.environment_map.is_some() || !scene.punctual_lights.is_empty() {
            let radius = 0.5 * (self.bounds_max - self.bounds_min).as_dvec3().length();
            let triangle_power: Vec<f64> = scene
                .lights
                .iter()
                .map(|l| {
                    let m = &scene.materials[scene.info[l.triangle as usize].material as usize];
                    l.area as f64 * (luminance(xyz(m.emission)).max(1e-6) as f64)
                })
                .collect();
            let mut power = triangle_power;
            let mut kinds: Vec<u32> = scene.lights.iter().map(|l| l.triangle).collect();
            let env_at = textures.len() as u32;
            let env_power = scene
                .environment_map
                .as_ref()
                .map(|m| 4.0 * std::f64::consts::PI * std::f64::consts::PI * radius * radius * m.mean_luminance());
            let mut offset = env_at;
            if let Some(m) = &scene.environment_map {
                offset += shared::environment::words(m.width, m.height);
                power.push(env_power.unwrap_or(0.0).max(1e-12));
                kinds.push(LIGHT_NOT_TRIANGLE | LIGHT_ENVIRONMENT_BIT | env_at);
            }
            let punctual_at = offset;
            for (i, l) in scene.punctual_lights.iter().enumerate() {
                power.push(l.power(radius).max(1e-12));
                kinds.push(LIGHT_NOT_TRIANGLE | (punctual_at + i as u32 * shared::punctual::WORDS));
            }
            let total: f64 = power.iter().sum();
            let mut running = 0.0;
            lights = Vec::with_capacity(power.len());
            for (i, (&p, &kind)) in power.iter().zip(&kinds).enumerate() {
                let pmf = p / total;
                running += pmf;
                let area = if i < scene.lights.len() { scene.lights[i].area } else { 0.0 };
                let cdf = if i + 1 == power.len() { 1.0 } else { running as f32 };
                lights.push(Light { triangle: kind, pmf: pmf as f32, cdf, area });
            }
            if let Some(m) = &scene.environment_map {
                let pmf = lights[scene.lights.len()].pmf;
                textures.extend(m.pack(pmf));
                self.environment_map = env_at + 1;
            }
            for l in &scene.punctual_lights {
                textures.extend_from_slice(bytemuck::cast_slice(&[l.layout()]));
            }
        }
        self.light_count = lights.len() as u32;
        if lights.is_empty() {
            lights.push(Light::default());
        }
        self.lights = lights;
        self.textures = textures;
    }

    /// The scene's bounds in world space (what a default camera frames).
    pub fn world_bounds(&self) -> (DVec3, DVec3) {
        (point_to_world(self.bounds_min, self.origin), point_to_world(self.bounds_max, self.origin))
    }

    /// Whether `s`'s camera can render this scene (its distance in the local frame): `params`
    /// without the connections' decision, which casts rays (`features::seen_light_share`).
    pub fn check_camera(&self, s: &RenderSettings) -> Result<()> {
        self.params(&RenderSettings { connect: crate::settings::Connect::Off, ..*s }, 0, 1).map(|_| ())
    }

    pub fn params(&self, s: &RenderSettings, sample_start: u32, sample_count: u32) -> Result<RenderParams> {
        let (right, up, forward) = s.camera.basis(s.aspect())?;
        let eye = point_to_local(s.camera.eye, self.origin);
        if !(eye.abs().max_element() <= MAX_EXTENT) {
            bail!(
                "camera: the eye lies {:e} units from the scene's local origin; kdtrace renders up to {MAX_EXTENT:e}",
                eye.abs().max_element()
            );
        }
        let f = crate::render::features::analyse(self, s);
        Ok(RenderParams {
            eye: eye.extend(0.0),
            right: right.extend(0.0),
            up: up.extend(0.0),
            forward: forward.extend(0.0),
            bounds_min: self.bounds_min.extend(0.0),
            bounds_max: self.bounds_max.extend(0.0),
            environment: s.environment.extend(0.0),
            width: s.width,
            height: s.height,
            sample_start,
            sample_count,
            seed: s.seed,
            max_bounces: s.max_bounces,
            rr_start: s.rr_start,
            light_count: self.light_count,
            inv_width: 1.0 / s.width as f32,
            inv_height: 1.0 / s.height as f32,
            // Renderers resolve `Auto` first; left unresolved it means the full stack.
            traversal: match s.traversal {
                Traversal::Full | Traversal::Auto => TRAVERSAL_FULL_STACK,
                Traversal::Short => TRAVERSAL_SHORT_STACK,
                Traversal::Wide => TRAVERSAL_WIDE_BVH,
            },
            aov: match s.aov {
                Aov::Radiance => AOV_RADIANCE,
                Aov::Cost => AOV_COST,
                Aov::Albedo => AOV_ALBEDO,
                Aov::Normal => AOV_NORMAL,
            },
            persistent_rounds: u32::MAX,
            sampler: s.sampler.tag(),
            live_count: 0,
            environment_map: self.environment_map,
            connect: u32::from(f.connect),
            light_pool: u32::from(f.light_pool),
            ..Default::default()
        })
    }

    /// Parameters that carry only what ray casting needs (scene bounds, light count).
    pub fn bounds_params(&self) -> RenderParams {
        RenderParams {
            bounds_min: self.bounds_min.extend(0.0),
            bounds_max: self.bounds_max.extend(0.0),
            light_count: self.light_count,
            ..Default::default()
        }
    }

    /// The wide BVH, built on the first call.
    pub fn wide_bvh(&self) -> &crate::bvh::WideBvh {
        self.wide.get_or_init(|| crate::bvh::build(&self.scene.triangles))
    }

    /// The wide BVH and the CPU lanes' split, built on the first call: both from one build where
    /// the BVH was not built yet. Only a render through the lanes asks for the split.
    pub fn wide_bvh_and_split(&self) -> &crate::bvh::WideBvh {
        use crate::bvh::split;
        // `KDTRACE_CPU_SPLIT=off` keeps one BVH for every ray (to compare the two).
        let off = std::env::var("KDTRACE_CPU_SPLIT").as_deref() == Ok("off");
        if self.split.get().is_none() {
            if self.alpha_masks || off {
                let _ = self.split.set(None);
            } else if self.wide.get().is_some() {
                let _ = self.split.set(split::build_split(&self.scene.triangles));
            } else {
                let (w, s) = split::build(&self.scene.triangles);
                let _ = self.split.set(s);
                let _ = self.wide.set(w);
            }
        }
        self.wide_bvh()
    }

    pub fn view<'a>(&'a self, params: &RenderParams) -> SceneView<'a> {
        // A view for the wide BVH carries the k-d tree only where it was built already.
        let kd = if params.traversal == TRAVERSAL_WIDE_BVH { self.kd.get() } else { Some(self.kd()) };
        let (nodes, indices, blocks) = match kd {
            Some(k) => (&k.tree.nodes[..], &k.tree.indices[..], &k.blocks[..]),
            None => (&[][..], &[][..], &[][..]),
        };
        let mut view = SceneView::new(
            params,
            nodes,
            indices,
            blocks,
            &self.scene.triangles,
            &self.scene.info,
            &self.scene.materials,
            &self.lights,
            &self.scene.attributes,
            &self.textures,
            &[],
        );
        view.alpha_masks = self.alpha_masks;
        if params.traversal == TRAVERSAL_WIDE_BVH {
            self.wide_bvh();
        }
        // Ray batches name their traversal per ray: a built BVH is always in the view.
        if let Some(wide) = self.wide.get() {
            view.wide = wide.view();
        }
        if let Some(Some(split)) = self.split.get() {
            view.split = split.view();
        }
        view
    }
}

/// Block `k` holds the triangles of `indices[8k .. 8k + 8]` (`BLOCK_WIDTH` = 8), one per lane
/// (`align_leaves` makes the list a whole number of blocks; lanes past a shorter list stay zero,
/// a degenerate triangle no ray hits). Only the CPU reads them; the GPU binds a placeholder.
pub fn leaf_blocks(indices: &[u32], triangles: &[Triangle]) -> Vec<TriBlock> {
    let width = BLOCK_WIDTH as usize;
    indices
        .par_chunks(width)
        .map(|ids| {
            let mut b = TriBlock::default();
            for (lane, &id) in ids.iter().enumerate() {
                b.set_lane(lane, &triangles[id as usize]);
            }
            b
        })
        .collect()
}

/// An accumulated image: per pixel the radiance sum in `xyz` and the count of zeroed
/// (non-finite or negative) samples in `w`, plus the triangle hit by sample 0's camera ray.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub sum: Vec<Vec4>,
    /// Per pixel the sum of squared radiance (`xyz`), for the variance.
    pub sum_sq: Vec<Vec4>,
    pub primary: Vec<u32>,
    /// The traversal that rendered it (`Auto` resolved for the device).
    pub traversal: Traversal,
    /// With adaptive sampling, the samples each pixel's sums hold (`spp` is then the most);
    /// without, every pixel holds `spp`.
    pub counts: Option<Vec<u32>>,
}

impl Rendered {
    /// The samples pixel `i` holds.
    pub fn count(&self, i: usize) -> u32 {
        self.counts.as_ref().map_or(self.spp, |c| c[i])
    }

    /// Mean radiance per pixel, linear RGB.
    pub fn mean(&self) -> Vec<[f32; 3]> {
        (0..self.sum.len())
            .map(|i| {
                let (s, k) = (self.sum[i], 1.0 / self.count(i) as f32);
                [s.x * k, s.y * k, s.z * k]
            })
            .collect()
    }

    /// The fewest, mean and most samples per pixel.
    pub fn spp_range(&self) -> (u32, f64, u32) {
        match &self.counts {
            Some(c) => (
                c.iter().copied().min().unwrap_or(0),
                c.iter().map(|&n| n as f64).sum::<f64>() / c.len().max(1) as f64,
                c.iter().copied().max().unwrap_or(0),
            ),
            None => (self.spp, self.spp as f64, self.spp),
        }
    }

    /// Per-sample variance of each pixel's radiance (unbiased, n − 1 denominator; 0 below two
    /// samples): with `mean` and `spp`, what a per-pixel test of the image needs.
    pub fn variance(&self) -> Vec<[f32; 3]> {
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .enumerate()
            .map(|(i, (s, q))| {
                let n = self.count(i) as f64;
                let v = |a: f32, b: f32| {
                    if n < 2.0 {
                        0.0
                    } else {
                        ((b as f64 - (a as f64) * (a as f64) / n) / (n - 1.0)).max(0.0) as f32
                    }
                };
                [v(s.x, q.x), v(s.y, q.y), v(s.z, q.z)]
            })
            .collect()
    }

    /// Mean, per-sample variance and sample count of every pixel, for the per-pixel tests of
    /// `metrics`.
    pub fn stats(&self) -> anyhow::Result<crate::image::metrics::PixelStats> {
        use crate::image::metrics::{LinearImage, PixelStats};
        Ok(PixelStats {
            mean: LinearImage::new(self.width, self.height, self.mean())?,
            variance: LinearImage::new(self.width, self.height, self.variance())?,
            count: (0..self.sum.len()).map(|i| self.count(i) as u64).collect(),
        })
    }

    /// Samples that were non-finite or negative and were zeroed.
    pub fn zeroed_samples(&self) -> u64 {
        self.sum.iter().map(|s| s.w as u64).sum()
    }
}

/// Progress callback: (samples done, samples in all) over the whole image.
pub type Progress<'a> = &'a (dyn Fn(u64, u64) + Sync);
