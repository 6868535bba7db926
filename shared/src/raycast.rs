//! Casting given rays without shading: the closest hit or any hit, with the traversal's work.
//!
//! The ray-casting kernel runs this per invocation and the CPU runs it per ray, so a batch of
//! rays can be compared device against device ray by ray, and rays/s can be measured for the
//! primary, ambient-occlusion and diffuse-bounce rays of Aila & Laine, "Understanding the
//! Efficiency of Ray Traversal on GPUs" (HPG 2009).
use crate::kdtree::{intersect, occluded_hit};
use crate::layout::{RayQuery, RayResult, RAY_ANY_HIT};
use crate::scene::SceneView;
use crate::vecmath::xyz;

#[inline]
pub fn cast_ray(scene: &SceneView, q: &RayQuery) -> RayResult {
    let (o, d) = (xyz(q.origin), xyz(q.dir));
    let hit = if (q.flags & RAY_ANY_HIT) != 0 { occluded_hit(scene, o, d, q.t_max) } else { intersect(scene, o, d, q.t_max) };
    RayResult { t: hit.t, triangle: hit.triangle, nodes: hit.nodes, tests: hit.tests }
}
