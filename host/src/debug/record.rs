//! What a replayed sample reports (`PathRecord` and its parts, serialised for a debugger's JSON
//! messages) and the recorder that collects it from the integrator's hooks (`Collector`, a
//! `shared::record::Recorder`).
//!
//! Positions are world coordinates in f64 (the scene's local frame plus `Compiled::origin`);
//! directions, normals and colours are the integrator's f32 values as they were.
use serde::Serialize;
use shared::glam::{DVec3, Vec3};
use shared::layout::{
    KdNode, MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_DIFFUSE, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED, NO_HIT,
};
use shared::material::DELTA_PDF;
use shared::record::{
    BsdfEvent, LightEvent, Recorder, SurfaceEvent, END_ABSORBED, END_AOV, END_BOUNCE_LIMIT, END_ESCAPED, END_ROULETTE,
    LIGHT_BLOCKED, LIGHT_DELTA, LIGHT_INVALID, LIGHT_UNBLOCKED, RAY_CAMERA, RAY_SHADOW,
};

/// The most k-d nodes, and the most triangle tests, a record keeps per ray: a ray through a
/// degenerate tree may visit far more, and a debugger's message should stay small. A ray that
/// went past either says so (`truncated`); its `nodes` and `tests` counts stay whole.
pub const MAX_RECORDED_PER_RAY: usize = 4096;

/// One sample of one pixel, replayed.
#[derive(Clone, Debug, Serialize)]
pub struct PathRecord {
    pub x: u32,
    pub y: u32,
    pub sample: u32,
    pub seed: u32,
    /// What the renderer adds to the pixel's sum for this sample: the path's radiance after
    /// `shared::numerics::sanitize`, linear RGB.
    pub radiance: [f32; 3],
    /// Whether the path's radiance was non-finite or negative and was zeroed (`radiance` is then
    /// zero; `raw_radiance` has what the path gave).
    pub zeroed: bool,
    pub raw_radiance: [f32; 3],
    /// Why the path ended: "escaped", "bounce_limit", "absorbed", "roulette" or "aov".
    pub end: &'static str,
    /// The camera ray: origin (the eye, world) and unit direction.
    pub camera_origin: [f64; 3],
    pub camera_direction: [f32; 3],
    /// The path's vertices in order, the camera ray's hit first. An auxiliary image (`--aov`)
    /// answers at the camera ray, `end` then "aov": the cost image with no vertex, the albedo and
    /// normal images with the first hit's, which neither emits nor samples anything.
    pub vertices: Vec<VertexRecord>,
    /// The ray that left the scene, where the path ended so.
    pub escaped: Option<EscapeRecord>,
}

/// One path vertex: the surface a camera or bounce ray hit and everything done there.
#[derive(Clone, Debug, Serialize)]
pub struct VertexRecord {
    /// Indirect bounces before this vertex (0: the camera ray's hit).
    pub bounce: u32,
    /// The ray that found it, as traced: origin (world) and unit direction.
    pub ray_origin: [f64; 3],
    pub ray_direction: [f32; 3],
    /// The hit point (world).
    pub position: [f64; 3],
    /// `position` in the image, in continuous pixel coordinates (x right, y down; pixel (i, j)
    /// covers [i, i + 1) × [j, j + 1)); `None` behind the camera.
    pub pixel: Option<[f64; 2]>,
    /// Distance along the ray, in units of its direction's length.
    pub t: f32,
    pub triangle: u32,
    /// The material's index in the scene's table, and its kind: "diffuse", "conductor",
    /// "dielectric", "plastic" or "principled".
    pub material: u32,
    pub material_kind: &'static str,
    /// The triangle's unit normal (counter-clockwise side), and the shading normal the BSDFs saw,
    /// turned toward the arriving ray.
    pub geometric_normal: [f32; 3],
    pub shading_normal: [f32; 3],
    /// Whether the ray arrived on the front (counter-clockwise) side.
    pub front: bool,
    /// Emission added here, where the surface emits toward the ray.
    pub emission: Option<EmissionRecord>,
    /// Next-event estimation here; `None` at a vertex that does none (no lights in the scene, or
    /// the path's last vertex).
    pub light: Option<LightRecord>,
    /// The connection to a light subpath's vertex here (`shared::connection`); `None` where the
    /// path does not connect (the setting, the scene, the path's last vertex).
    pub connection: Option<ConnectionRecord>,
    /// The BSDF sample here; `None` at the path's last vertex.
    pub bsdf: Option<BsdfRecord>,
    /// The path's throughput after this vertex (its BSDF weight and roulette applied).
    pub throughput: [f32; 3],
    pub roulette: Option<RouletteRecord>,
    /// The traversal of the ray that found this vertex.
    #[serde(flatten)]
    pub traversal: TraversalRecord,
}

/// The k-d traversal of one ray.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TraversalRecord {
    /// Nodes in the order visited (the root is 0; again after each short-stack restart).
    pub nodes_visited: Vec<u32>,
    /// The triangles of the visited leaves' index runs, in the order tested (a triangle in
    /// several leaves appears once per leaf).
    pub triangles_tested: Vec<u32>,
    /// The traversal's own counts: nodes visited, triangles tested, short-stack restarts.
    pub nodes: u32,
    pub tests: u32,
    pub restarts: u32,
    /// Whether `nodes_visited` or `triangles_tested` stopped at `MAX_RECORDED_PER_RAY`.
    pub truncated: bool,
}

/// Emission at a vertex.
#[derive(Clone, Debug, Serialize)]
pub struct EmissionRecord {
    /// The emitted radiance toward the ray.
    pub emitted: [f32; 3],
    /// Its MIS weight against light sampling (1 for the camera ray's hit and where the surface
    /// is not in the light table).
    pub mis_weight: f32,
    /// Throughput × emitted × weight: what was added to the radiance.
    pub added: [f32; 3],
}

/// Next-event estimation at a vertex.
#[derive(Clone, Debug, Serialize)]
pub struct LightRecord {
    /// "unblocked" (the shadow ray reached the light), "blocked", "invalid" (no shadow ray: the
    /// light faces away, or the BSDF cannot scatter toward it) or "delta" (a smooth material:
    /// no light is sampled).
    pub status: &'static str,
    /// Whether the shadow ray hit something on its way (only "blocked").
    pub blocked: bool,
    /// The light's index in the light table, its triangle, and the point sampled on it (world)
    /// with its pixel; `None` for "delta".
    pub light: Option<u32>,
    pub triangle: Option<u32>,
    pub point: Option<[f64; 3]>,
    pub pixel: Option<[f64; 2]>,
    /// Solid-angle pdf of the light sample (0 where no shadow ray was traced), the BSDF's pdf
    /// for the same direction, and the light sample's MIS weight (0 where no shadow ray was
    /// traced).
    pub light_pdf: f32,
    pub bsdf_pdf: f32,
    pub mis_weight: f32,
    /// What was added to the radiance (zero unless "unblocked").
    pub contribution: [f32; 3],
    /// The shadow ray, where one was traced.
    pub shadow_ray: Option<ShadowRayRecord>,
}

/// A shadow ray toward the light sample or the light vertex.
#[derive(Clone, Debug, Serialize)]
pub struct ShadowRayRecord {
    /// Origin (world) and direction: the ray ends at `t_max` × direction, just short of its target.
    pub origin: [f64; 3],
    pub direction: [f32; 3],
    pub t_max: f32,
    /// The triangle found in the way (any hit, not necessarily the closest), if any.
    pub occluder: Option<u32>,
    #[serde(flatten)]
    pub traversal: TraversalRecord,
}

/// The connection to a light subpath's vertex at an eye vertex.
#[derive(Clone, Debug, Serialize)]
pub struct ConnectionRecord {
    /// "unblocked" (the shadow ray reached the light vertex), "blocked", or "invalid" (no shadow
    /// ray: no light vertex, or the two do not face each other).
    pub status: &'static str,
    /// The light vertex joined (world) and its pixel, where a shadow ray was cast.
    pub point: Option<[f64; 3]>,
    pub pixel: Option<[f64; 2]>,
    /// What was added to the radiance (zero unless "unblocked").
    pub contribution: [f32; 3],
    /// The shadow ray, where one was cast.
    pub shadow_ray: Option<ShadowRayRecord>,
}

/// The BSDF sample at a vertex.
#[derive(Clone, Debug, Serialize)]
pub struct BsdfRecord {
    /// The sampled direction (unit, away from the surface).
    pub wi: [f32; 3],
    /// Its solid-angle pdf; `delta` when the lobe is a delta (the pdf is then f32::MAX).
    pub pdf: f32,
    pub delta: bool,
    /// f·|cos|/pdf.
    pub weight: [f32; 3],
    /// Whether the material picked a lobe, and the uniform it picked with.
    pub picks_lobe: bool,
    pub u_pick: f32,
    /// Whether the path went on with it (pdf > 0 and consistent with the normals).
    pub valid: bool,
}

/// Russian roulette at a vertex.
#[derive(Clone, Debug, Serialize)]
pub struct RouletteRecord {
    /// The probability of going on, and the uniform compared with it.
    pub survival: f32,
    pub uniform: f32,
    pub survived: bool,
}

/// The ray that left the scene.
#[derive(Clone, Debug, Serialize)]
pub struct EscapeRecord {
    pub bounce: u32,
    pub ray_origin: [f64; 3],
    pub ray_direction: [f32; 3],
    /// Throughput × environment: what was added.
    pub environment: [f32; 3],
    #[serde(flatten)]
    pub traversal: TraversalRecord,
}

/// The name of a material kind (`layout::MATERIAL_*`).
pub fn material_kind_name(kind: u32) -> &'static str {
    match kind {
        MATERIAL_DIFFUSE => "diffuse",
        MATERIAL_CONDUCTOR => "conductor",
        MATERIAL_DIELECTRIC => "dielectric",
        MATERIAL_PLASTIC => "plastic",
        MATERIAL_PRINCIPLED => "principled",
        _ => "unknown",
    }
}

fn end_name(reason: u32) -> &'static str {
    match reason {
        END_ESCAPED => "escaped",
        END_BOUNCE_LIMIT => "bounce_limit",
        END_ABSORBED => "absorbed",
        END_ROULETTE => "roulette",
        END_AOV => "aov",
        _ => "unknown",
    }
}

fn light_status_name(status: u32) -> &'static str {
    match status {
        LIGHT_UNBLOCKED => "unblocked",
        LIGHT_BLOCKED => "blocked",
        LIGHT_INVALID => "invalid",
        LIGHT_DELTA => "delta",
        _ => "unknown",
    }
}

pub(crate) fn arr(v: Vec3) -> [f32; 3] {
    v.to_array()
}

/// A ray being traced: what `Recorder::ray` announced and the nodes seen since.
struct Tracing {
    kind: u32,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    traversal: TraversalRecord,
}

/// A traced ray with its answer.
struct Traced {
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    triangle: u32,
    t: f32,
    traversal: TraversalRecord,
}

/// The recorder a replay runs with: it turns the integrator's events into vertex records.
/// `nodes` and `indices` are the tree the traversal runs on (leaves expand to their triangles);
/// `origin` the local frame's world position; `project` maps a world point into the image.
pub(crate) struct Collector<'a> {
    nodes: &'a [KdNode],
    indices: &'a [u32],
    origin: DVec3,
    project: &'a dyn Fn(DVec3) -> Option<[f64; 2]>,
    tracing: Option<Tracing>,
    /// The last camera or bounce ray, until its vertex or escape takes it.
    path_ray: Option<Traced>,
    /// The last shadow ray, until the light record takes it.
    shadow_ray: Option<Traced>,
    /// The throughput so far (what arrives at the next vertex).
    throughput: Vec3,
    pub camera_origin: [f64; 3],
    pub camera_direction: [f32; 3],
    pub vertices: Vec<VertexRecord>,
    pub escaped: Option<EscapeRecord>,
    pub end: &'static str,
}

impl<'a> Collector<'a> {
    pub fn new(
        nodes: &'a [KdNode],
        indices: &'a [u32],
        origin: DVec3,
        project: &'a dyn Fn(DVec3) -> Option<[f64; 2]>,
    ) -> Self {
        Self {
            nodes,
            indices,
            origin,
            project,
            tracing: None,
            path_ray: None,
            shadow_ray: None,
            throughput: Vec3::ONE,
            camera_origin: [f64::NAN; 3],
            camera_direction: [f32::NAN; 3],
            vertices: Vec::new(),
            escaped: None,
            end: "unknown",
        }
    }

    fn world(&self, p: Vec3) -> DVec3 {
        p.as_dvec3() + self.origin
    }

    fn vertex(&mut self) -> Option<&mut VertexRecord> {
        self.vertices.last_mut()
    }

    fn shadow_record(&self, r: Traced) -> ShadowRayRecord {
        ShadowRayRecord {
            origin: self.world(r.origin).to_array(),
            direction: arr(r.dir),
            t_max: r.t_max,
            occluder: (r.triangle != NO_HIT).then_some(r.triangle),
            traversal: r.traversal,
        }
    }
}

impl Recorder for Collector<'_> {
    const ACTIVE: bool = true;

    fn ray(&mut self, kind: u32, origin: Vec3, dir: Vec3, t_max: f32) {
        if kind == RAY_CAMERA {
            self.camera_origin = self.world(origin).to_array();
            self.camera_direction = arr(dir);
        }
        self.tracing = Some(Tracing { kind, origin, dir, t_max, traversal: TraversalRecord::default() });
    }

    fn node(&mut self, node: u32) {
        let Some(r) = self.tracing.as_mut() else { return };
        let t = &mut r.traversal;
        if t.nodes_visited.len() >= MAX_RECORDED_PER_RAY {
            t.truncated = true;
            return;
        }
        t.nodes_visited.push(node);
        let n = self.nodes[node as usize];
        if n.is_leaf() {
            let (first, count) = (n.first_index() as usize, n.count() as usize);
            let room = MAX_RECORDED_PER_RAY - t.triangles_tested.len();
            t.truncated |= count > room;
            t.triangles_tested.extend_from_slice(&self.indices[first..first + count.min(room)]);
        }
    }

    fn traced(&mut self, triangle: u32, t: f32, nodes: u32, tests: u32, restarts: u32) {
        let Some(r) = self.tracing.take() else { return };
        let traversal = TraversalRecord { nodes, tests, restarts, ..r.traversal };
        let traced = Traced { origin: r.origin, dir: r.dir, t_max: r.t_max, triangle, t, traversal };
        if r.kind == RAY_SHADOW {
            self.shadow_ray = Some(traced);
        } else {
            self.path_ray = Some(traced);
        }
    }

    fn escaped(&mut self, added: Vec3) {
        let Some(r) = self.path_ray.take() else { return };
        self.escaped = Some(EscapeRecord {
            bounce: self.vertices.len() as u32,
            ray_origin: self.world(r.origin).to_array(),
            ray_direction: arr(r.dir),
            environment: arr(added),
            traversal: r.traversal,
        });
    }

    fn surface(&mut self, s: SurfaceEvent) {
        let r = self.path_ray.take();
        let position = self.world(s.position);
        let (origin, dir, t, traversal) = match r {
            Some(r) => (self.world(r.origin).to_array(), arr(r.dir), r.t, r.traversal),
            None => ([f64::NAN; 3], [f32::NAN; 3], f32::NAN, TraversalRecord::default()),
        };
        self.vertices.push(VertexRecord {
            bounce: s.bounce,
            ray_origin: origin,
            ray_direction: dir,
            position: position.to_array(),
            pixel: (self.project)(position),
            t,
            triangle: s.triangle,
            material: s.material,
            material_kind: material_kind_name(s.material_kind),
            geometric_normal: arr(s.geometric_normal),
            shading_normal: arr(s.shading_normal),
            front: s.front,
            emission: None,
            light: None,
            connection: None,
            bsdf: None,
            throughput: arr(self.throughput),
            roulette: None,
            traversal,
        });
    }

    fn emission(&mut self, le: Vec3, mis_weight: f32, added: Vec3) {
        if let Some(v) = self.vertex() {
            v.emission = Some(EmissionRecord { emitted: arr(le), mis_weight, added: arr(added) });
        }
    }

    fn light(&mut self, l: LightEvent) {
        // The shadow ray traced for this sample, if one was.
        let shadow = self.shadow_ray.take().filter(|_| (l.status == LIGHT_UNBLOCKED) | (l.status == LIGHT_BLOCKED));
        let delta = l.status == LIGHT_DELTA;
        let point = (!delta).then(|| self.world(l.point));
        let shadow_ray = shadow.map(|r| self.shadow_record(r));
        let record = LightRecord {
            status: light_status_name(l.status),
            blocked: l.status == LIGHT_BLOCKED,
            light: (!delta).then_some(l.light),
            triangle: (!delta).then_some(l.triangle),
            point: point.map(|p| p.to_array()),
            pixel: point.and_then(|p| (self.project)(p)),
            light_pdf: l.light_pdf,
            bsdf_pdf: l.bsdf_pdf,
            mis_weight: l.mis_weight,
            contribution: arr(l.contribution),
            shadow_ray,
        };
        if let Some(v) = self.vertex() {
            v.light = Some(record);
        }
    }

    fn connection(&mut self, cast: bool, added: Vec3) {
        let shadow = if cast { self.shadow_ray.take() } else { None };
        let blocked = shadow.as_ref().is_some_and(|r| r.triangle != NO_HIT);
        // The ray ends just short of the light vertex: its direction is the whole segment.
        let point = shadow.as_ref().map(|r| self.world(r.origin + r.dir));
        let record = ConnectionRecord {
            status: match (&shadow, blocked) {
                (None, _) => "invalid",
                (Some(_), true) => "blocked",
                (Some(_), false) => "unblocked",
            },
            point: point.map(|p| p.to_array()),
            pixel: point.and_then(|p| (self.project)(p)),
            contribution: arr(added),
            shadow_ray: shadow.map(|r| self.shadow_record(r)),
        };
        if let Some(v) = self.vertex() {
            v.connection = Some(record);
        }
    }

    fn bsdf(&mut self, b: BsdfEvent) {
        self.throughput = b.throughput;
        let Some(v) = self.vertex() else { return };
        v.bsdf = Some(BsdfRecord {
            wi: arr(b.wi),
            pdf: b.pdf,
            delta: b.pdf == DELTA_PDF,
            weight: arr(b.weight),
            picks_lobe: b.picks_lobe,
            u_pick: b.u_pick,
            valid: b.valid,
        });
        v.throughput = arr(b.throughput);
    }

    fn roulette(&mut self, survival: f32, u: f32, survived: bool, throughput: Vec3) {
        self.throughput = throughput;
        let Some(v) = self.vertex() else { return };
        v.roulette = Some(RouletteRecord { survival, uniform: u, survived });
        v.throughput = arr(throughput);
    }

    fn end(&mut self, reason: u32, _radiance: Vec3) {
        self.end = end_name(reason);
    }
}
