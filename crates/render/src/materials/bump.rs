//! Perturbed shading normals, as pbrt-v4 does them for every material: bump mapping by a
//! displacement texture (the surface moved along its normal by the texture's value, the
//! normal taken from the moved surface's finite differences in u and v) and tangent-space
//! normal maps.

use crate::math::Frame;
use crate::shapes::SurfaceHit;
use crate::textures::{FloatTexture, TextureEvalContext};
use glam::{Vec2, Vec3A};
use kiln_scene::TextureImage;
use std::sync::Arc;

#[derive(Debug, Clone, Default)]
pub enum Perturbation {
    #[default]
    None,
    Bump(FloatTexture),
    NormalMap(Arc<TextureImage>),
}

impl Perturbation {
    pub fn is_none(&self) -> bool {
        matches!(self, Perturbation::None)
    }

    /// Replaces `hit`'s shading normal and dp/du by the perturbed ones; `ctx` is the hit's
    /// texture context (its footprint sets bump mapping's finite-difference steps).
    pub fn apply(&self, hit: &mut SurfaceHit, ctx: &TextureEvalContext) {
        let (dpdu, dpdv) = shading_derivatives(hit);
        let (dpdu, dpdv) = match self {
            Perturbation::None => return,
            Perturbation::Bump(d) => bump(d, hit.ns, dpdu, dpdv, ctx),
            Perturbation::NormalMap(image) => normal_map(image, hit.ns, dpdu, dpdv, hit.uv),
        };
        let mut ns = dpdu.cross(dpdv).normalize_or_zero();
        if !ns.is_finite() || ns == Vec3A::ZERO {
            return;
        }
        // The shading normal stays on the geometric normal's side.
        if ns.dot(hit.ng) < 0.0 {
            ns = -ns;
        }
        hit.ns = ns;
        hit.dpdu = dpdu;
    }
}

/// The shading dp/du and dp/dv as pbrt-v4 keeps them: the shape's own where the shading
/// normal is the geometric one; where interpolated normals tilt it, dp/du made
/// perpendicular to it and dp/dv = n × dp/du (pbrt-v4's triangles).
fn shading_derivatives(hit: &SurfaceHit) -> (Vec3A, Vec3A) {
    if hit.ns == hit.ng {
        return (hit.dpdu, hit.dpdv);
    }
    let ts = hit.ns.cross(hit.dpdu);
    if ts.length_squared() > 0.0 {
        (ts.cross(hit.ns), ts)
    } else {
        let f = Frame::from_z(hit.ns);
        (f.x, f.y)
    }
}

fn bump(
    displacement: &FloatTexture,
    n: Vec3A,
    dpdu: Vec3A,
    dpdv: Vec3A,
    ctx: &TextureEvalContext,
) -> (Vec3A, Vec3A) {
    let step = |a: f32, b: f32| {
        let d = 0.5 * (a.abs() + b.abs());
        if d == 0.0 { 0.0005 } else { d }
    };
    let du = step(ctx.dudx, ctx.dudy);
    let dv = step(ctx.dvdx, ctx.dvdy);
    let displaced =
        |p: Vec3A, uv: Vec2| displacement.evaluate(&TextureEvalContext { p, uv, ..*ctx });
    let base = displacement.evaluate(ctx);
    let u_displace = displaced(ctx.p + du * dpdu, ctx.uv + Vec2::new(du, 0.0));
    let v_displace = displaced(ctx.p + dv * dpdv, ctx.uv + Vec2::new(0.0, dv));
    // pbrt-v4 adds displace·dn/du too; Kiln's hits carry no dn/du, and the term matters only
    // where a large constant offset sits on a strongly curved surface.
    (
        dpdu + (u_displace - base) / du * n,
        dpdv + (v_displace - base) / dv * n,
    )
}

fn normal_map(
    image: &TextureImage,
    n: Vec3A,
    dpdu: Vec3A,
    dpdv: Vec3A,
    uv: Vec2,
) -> (Vec3A, Vec3A) {
    // The image's top row is v = 1; its values map [0, 1] to [-1, 1].
    let st = Vec2::new(uv.x, 1.0 - uv.y);
    let c = |i| 2.0 * bilerp_repeat(image, st, i) - 1.0;
    let local = Vec3A::new(c(0), c(1), c(2)).normalize_or_zero();
    let frame = Frame::new(n, dpdu);
    let ns = frame.to_world(local);
    let (ulen, vlen) = (dpdu.length(), dpdv.length());
    let t = (dpdu - ns * ns.dot(dpdu)).normalize_or_zero() * ulen;
    (t, ns.cross(t).normalize_or_zero() * vlen)
}

/// Channel `c` (or the last one, for grey images) of `image` at `st`, bilinearly between
/// texel centres, repeating at the edges.
fn bilerp_repeat(image: &TextureImage, st: Vec2, c: u32) -> f32 {
    let c = c.min(image.channels - 1);
    let (w, h) = (image.width as i64, image.height as i64);
    let (x, y) = (st.x * w as f32 - 0.5, st.y * h as f32 - 0.5);
    let (fx, fy) = (x.floor(), y.floor());
    let (dx, dy) = (x - fx, y - fy);
    let texel = |i: i64, j: i64| image.channel(i.rem_euclid(w) as u32, j.rem_euclid(h) as u32, c);
    let (i, j) = (fx as i64, fy as i64);
    (1.0 - dx) * (1.0 - dy) * texel(i, j)
        + dx * (1.0 - dy) * texel(i + 1, j)
        + (1.0 - dx) * dy * texel(i, j + 1)
        + dx * dy * texel(i + 1, j + 1)
}
