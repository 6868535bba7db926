//! Shadow rays prepared first and traced at one place: next-event estimation and the connection
//! to a light subpath each describe their shadow ray and what it adds if it gets through
//! (`ShadowRay`, `LightSample`), and the integrator's path loop traces both through its one query,
//! the one that also finds the path's vertices (`integrator::trace_path`). A shader inlines the
//! whole traversal at every query, so one query for every ray, where there were six (the path's,
//! a triangle's light sample, another light's, the connection, the pooled connection and the
//! light subpath's first ray), keeps the kernel smaller and its compile shorter (README, "Shader
//! size").
use crate::glam::Vec3;
use crate::integrator::SHADOW_EPSILON;
use crate::layout::RenderParams;
use crate::raycast::query_recorded;
use crate::record::{LightEvent, Recorder, LIGHT_UNBLOCKED, RAY_SHADOW};
use crate::scene::SceneView;

/// A shadow ray to trace, or none (`active` false).
#[derive(Clone, Copy)]
pub struct ShadowRay {
    pub active: bool,
    pub from: Vec3,
    pub dir: Vec3,
    /// The ray's reach in units of `dir`.
    pub t_max: f32,
}

impl ShadowRay {
    pub const NONE: ShadowRay = ShadowRay { active: false, from: Vec3::ZERO, dir: Vec3::ZERO, t_max: 0.0 };

    /// A ray from `from` along `dir` up to `t_max`.
    #[inline(always)]
    pub fn new(from: Vec3, dir: Vec3, t_max: f32) -> ShadowRay {
        ShadowRay { active: true, from, dir, t_max }
    }

    /// The ray from `from` to `target`, stopping `SHADOW_EPSILON` of the way short of it.
    #[inline(always)]
    pub fn toward(from: Vec3, target: Vec3) -> ShadowRay {
        ShadowRay::new(from, target - from, 1.0 - SHADOW_EPSILON)
    }

    /// Whether the ray is cast and reaches its end unblocked, telling `rec` of it as a shadow ray.
    #[inline(always)]
    pub fn open<R: Recorder>(&self, scene: &SceneView, p: &RenderParams, rec: &mut R) -> bool {
        let mut open = false;
        if self.active {
            rec.ray(RAY_SHADOW, self.from, self.dir, self.t_max);
            let shadow = query_recorded(scene, p.traversal, self.from, self.dir, self.t_max, true, rec);
            rec.traced(shadow.hit.triangle, shadow.hit.t, shadow.hit.nodes, shadow.hit.tests, shadow.restarts);
            open = !shadow.hit.is_hit();
        }
        open
    }
}

/// A light sample of next-event estimation: its event for a recorder (`LIGHT_BLOCKED` where
/// the ray is cast), its shadow ray and the radiance it adds if the ray gets through.
#[derive(Clone, Copy)]
pub struct LightSample {
    pub event: LightEvent,
    pub ray: ShadowRay,
    pub added: Vec3,
}

impl LightSample {
    /// Adds the sample's radiance to `radiance` if its ray got through (`open`), and tells `rec`.
    #[inline(always)]
    pub fn finish<R: Recorder>(self, open: bool, radiance: &mut Vec3, rec: &mut R) {
        let mut event = self.event;
        if self.ray.active & open {
            *radiance += self.added;
            event.status = LIGHT_UNBLOCKED;
            event.contribution = self.added;
        }
        rec.light(event);
    }
}
