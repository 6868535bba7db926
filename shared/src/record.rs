//! Recording hooks in the integrator and the k-d traversals: what a path did, event by event, for
//! a debugger that replays one pixel sample on the CPU (`host::debug`).
//!
//! The integrator (`integrator::trace_sample_recorded`) and the traversals (`kdtree`,
//! `short_stack`, through `raycast::query_recorded`) are generic over a `Recorder` and call its
//! hooks as things happen. Every hook has an empty default body, and `NoRecord`, the recorder the
//! renderers use on both devices, is zero-sized and overrides none: once inlined its calls are
//! nothing, and the work done only to report (a shading normal at a path's last vertex) sits
//! behind `Recorder::ACTIVE`, a constant false for it. So the replay runs the very code that
//! renders, not a second integrator, and the render pays nothing for it.
//!
//! Hooks take plain values (floats, integers, vectors, flags, and small `Copy` structs of those),
//! never references into the scene's buffers: a recorder keeps what it is told.
use crate::glam::Vec3;

/// `Recorder::ray`'s kind: the camera ray (closest hit).
pub const RAY_CAMERA: u32 = 0;
/// A ray continuing the path after a BSDF sample (closest hit).
pub const RAY_BOUNCE: u32 = 1;
/// A shadow ray of next-event estimation toward a point on a light (any hit).
pub const RAY_SHADOW: u32 = 2;

/// `LightEvent::status`: the shadow ray was traced and reached the light; `contribution` added.
pub const LIGHT_UNBLOCKED: u32 = 0;
/// The shadow ray was traced and something lies in between; nothing added.
pub const LIGHT_BLOCKED: u32 = 1;
/// The sample cannot contribute, so no shadow ray was traced: the light faces away, the BSDF's
/// pdf for the direction is zero, or the direction is on the wrong side of the shading normal.
pub const LIGHT_INVALID: u32 = 2;
/// The material is a delta lobe (a smooth mirror or glass): no light is sampled there, and no
/// uniforms were spent beyond the set drawn for the vertex.
pub const LIGHT_DELTA: u32 = 3;

/// `Recorder::end`'s reason: the ray left the scene (environment added, if any).
pub const END_ESCAPED: u32 = 0;
/// The vertex was the last the bounce limit allows (or the scene reflects no light): its
/// emission was added and the path stopped there.
pub const END_BOUNCE_LIMIT: u32 = 1;
/// The BSDF sample was invalid (zero pdf, or a direction the shading normal puts on the wrong
/// side): the path was absorbed.
pub const END_ABSORBED: u32 = 2;
/// Russian roulette ended the path.
pub const END_ROULETTE: u32 = 3;
/// An auxiliary image (cost, albedo, normal) answered at the camera ray.
pub const END_AOV: u32 = 4;

/// The surface at a path vertex, before anything is shaded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceEvent {
    /// Indirect bounces taken before this vertex (0: the camera ray's hit).
    pub bounce: u32,
    /// The hit point, in the scene's local frame (`hit_point`, the same value shading uses).
    pub position: Vec3,
    pub triangle: u32,
    /// The index of the material in the scene's material table, and its kind
    /// (`layout::MATERIAL_*`).
    pub material: u32,
    pub material_kind: u32,
    /// The triangle's unit geometric normal, counter-clockwise side (not turned).
    pub geometric_normal: Vec3,
    /// The shading normal the BSDFs see, turned toward the side the ray arrived from.
    pub shading_normal: Vec3,
    /// Whether the ray arrived on the front (counter-clockwise) side.
    pub front: bool,
}

/// Next-event estimation at one vertex: the point picked on a light and what came of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightEvent {
    /// `LIGHT_UNBLOCKED`, `LIGHT_BLOCKED`, `LIGHT_INVALID` or `LIGHT_DELTA` (then every other
    /// field is zero).
    pub status: u32,
    /// The light's index in the light table and its triangle.
    pub light: u32,
    pub triangle: u32,
    /// The point on the light, local frame.
    pub point: Vec3,
    /// The light sample's solid-angle pdf, the BSDF's pdf for the same direction, and the power
    /// heuristic's weight of the light sample (0 where no shadow ray was traced).
    pub light_pdf: f32,
    pub bsdf_pdf: f32,
    pub mis_weight: f32,
    /// What was added to the path's radiance (throughput included); zero unless unblocked.
    pub contribution: Vec3,
}

/// The BSDF sample that continues (or ends) the path at one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfEvent {
    pub wi: Vec3,
    /// Solid-angle pdf (`material::DELTA_PDF` for a delta lobe; 0 for no sample).
    pub pdf: f32,
    /// f·|cos|/pdf.
    pub weight: Vec3,
    /// Whether the material picked a lobe, and the uniform it picked with (0 where it did not).
    pub picks_lobe: bool,
    pub u_pick: f32,
    /// Whether the path goes on with it (pdf > 0 and the direction consistent with the normals).
    pub valid: bool,
    /// The throughput after this sample's weight (unchanged when not valid).
    pub throughput: Vec3,
}

/// Hooks the integrator and the traversals call at each event. Every one does nothing by
/// default; a recorder overrides those it wants.
pub trait Recorder {
    /// Whether the recorder keeps anything: values computed only to be reported (the shading
    /// normal of a path's last vertex) are computed only where this is true.
    const ACTIVE: bool = false;

    /// A ray query starts: `kind` is `RAY_CAMERA`, `RAY_BOUNCE` or `RAY_SHADOW`.
    #[inline(always)]
    fn ray(&mut self, _kind: u32, _origin: Vec3, _dir: Vec3, _t_max: f32) {}

    /// The traversal visits k-d node `node` (the root is 0), in the order it visits them; a
    /// leaf's triangles are the index run the node names.
    #[inline(always)]
    fn node(&mut self, _node: u32) {}

    /// The query that `ray` started is answered: the triangle hit (`layout::NO_HIT` for none)
    /// at distance `t`, nodes visited, triangles tested, and short-stack restarts.
    #[inline(always)]
    fn traced(&mut self, _triangle: u32, _t: f32, _nodes: u32, _tests: u32, _restarts: u32) {}

    /// A camera or bounce ray left the scene: `added` is the environment's radiance times the
    /// throughput (zero without an environment).
    #[inline(always)]
    fn escaped(&mut self, _added: Vec3) {}

    /// The surface a camera or bounce ray hit.
    #[inline(always)]
    fn surface(&mut self, _s: SurfaceEvent) {}

    /// The vertex emits toward the ray: the emitted radiance `le`, its MIS weight against light
    /// sampling, and what was added (throughput included). Not called where nothing is emitted.
    #[inline(always)]
    fn emission(&mut self, _le: Vec3, _mis_weight: f32, _added: Vec3) {}

    /// Next-event estimation at the vertex; a traced shadow ray's `ray`, `node` and `traced`
    /// calls come before it.
    #[inline(always)]
    fn light(&mut self, _l: LightEvent) {}

    /// The connection to a light vertex at the vertex (`connection`): whether a shadow ray was
    /// cast (its `ray`, `node` and `traced` calls come before it; none where the two cannot see
    /// each other) and what it added (zero where it was blocked or not cast). Called at every
    /// vertex that connects, after `light`.
    #[inline(always)]
    fn connection(&mut self, _cast: bool, _added: Vec3) {}

    /// The BSDF sample at the vertex.
    #[inline(always)]
    fn bsdf(&mut self, _b: BsdfEvent) {}

    /// Russian roulette: the survival probability, the uniform compared with it, whether the
    /// path survived, and the throughput after it (divided by `survival` when it survived).
    #[inline(always)]
    fn roulette(&mut self, _survival: f32, _u: f32, _survived: bool, _throughput: Vec3) {}

    /// The path ends (`END_*`) with this radiance (before the renderer's `sanitize`).
    #[inline(always)]
    fn end(&mut self, _reason: u32, _radiance: Vec3) {}
}

/// The recorder that records nothing: what every renderer passes.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoRecord;

impl Recorder for NoRecord {}

/// `rec` where `on`, else nothing: a query that serves rays the recorder hears of and rays it
/// does not (the integrator's path rays and its light subpath's first ray) passes it this.
pub struct Gated<'a, R: Recorder> {
    pub rec: &'a mut R,
    pub on: bool,
}

impl<R: Recorder> Recorder for Gated<'_, R> {
    const ACTIVE: bool = R::ACTIVE;

    #[inline(always)]
    fn ray(&mut self, kind: u32, origin: Vec3, dir: Vec3, t_max: f32) {
        if self.on {
            self.rec.ray(kind, origin, dir, t_max)
        }
    }

    #[inline(always)]
    fn node(&mut self, node: u32) {
        if self.on {
            self.rec.node(node)
        }
    }

    #[inline(always)]
    fn traced(&mut self, triangle: u32, t: f32, nodes: u32, tests: u32, restarts: u32) {
        if self.on {
            self.rec.traced(triangle, t, nodes, tests, restarts)
        }
    }

    #[inline(always)]
    fn escaped(&mut self, added: Vec3) {
        if self.on {
            self.rec.escaped(added)
        }
    }

    #[inline(always)]
    fn surface(&mut self, s: SurfaceEvent) {
        if self.on {
            self.rec.surface(s)
        }
    }

    #[inline(always)]
    fn emission(&mut self, le: Vec3, mis_weight: f32, added: Vec3) {
        if self.on {
            self.rec.emission(le, mis_weight, added)
        }
    }

    #[inline(always)]
    fn light(&mut self, l: LightEvent) {
        if self.on {
            self.rec.light(l)
        }
    }

    #[inline(always)]
    fn connection(&mut self, cast: bool, added: Vec3) {
        if self.on {
            self.rec.connection(cast, added)
        }
    }

    #[inline(always)]
    fn bsdf(&mut self, b: BsdfEvent) {
        if self.on {
            self.rec.bsdf(b)
        }
    }

    #[inline(always)]
    fn roulette(&mut self, survival: f32, u: f32, survived: bool, throughput: Vec3) {
        if self.on {
            self.rec.roulette(survival, u, survived, throughput)
        }
    }

    #[inline(always)]
    fn end(&mut self, reason: u32, radiance: Vec3) {
        if self.on {
            self.rec.end(reason, radiance)
        }
    }
}
