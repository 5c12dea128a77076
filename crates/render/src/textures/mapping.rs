//! Texture mappings: how a surface point becomes texture coordinates, with their
//! derivatives across the pixel footprint (for filtering).
//!
//! 2D: uv (scaled and offset surface coordinates), spherical, cylindrical and planar; 3D:
//! the point in the texture's own space (the inverse of the transform current at the
//! `Texture` directive), for solid textures.

use super::TextureEvalContext;
use glam::{Affine3A, DMat4, Vec2, Vec3A};
use kiln_scene::Mapping2D as Desc;
use std::f32::consts::{PI, TAU};

/// 2D texture coordinates and how they change from one pixel to the next.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TexCoord2D {
    pub st: Vec2,
    pub dsdx: f32,
    pub dsdy: f32,
    pub dtdx: f32,
    pub dtdy: f32,
}

/// A point in texture space and its differentials.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TexCoord3D {
    pub p: Vec3A,
    pub dpdx: Vec3A,
    pub dpdy: Vec3A,
}

#[derive(Debug, Clone)]
pub enum Mapping2D {
    Uv {
        su: f32,
        sv: f32,
        du: f32,
        dv: f32,
    },
    Spherical {
        texture_from_world: Affine3A,
    },
    Cylindrical {
        texture_from_world: Affine3A,
    },
    Planar {
        texture_from_world: Affine3A,
        vs: Vec3A,
        vt: Vec3A,
        ds: f32,
        dt: f32,
    },
}

fn affine(m: &DMat4) -> Affine3A {
    Affine3A::from_mat4(m.as_mat4())
}

impl Mapping2D {
    pub fn from_description(desc: &Desc) -> Mapping2D {
        match desc {
            Desc::Uv { su, sv, du, dv } => Mapping2D::Uv {
                su: *su,
                sv: *sv,
                du: *du,
                dv: *dv,
            },
            Desc::Spherical { texture_from_world } => Mapping2D::Spherical {
                texture_from_world: affine(texture_from_world),
            },
            Desc::Cylindrical { texture_from_world } => Mapping2D::Cylindrical {
                texture_from_world: affine(texture_from_world),
            },
            Desc::Planar {
                texture_from_world,
                vs,
                vt,
                ds,
                dt,
            } => Mapping2D::Planar {
                texture_from_world: affine(texture_from_world),
                vs: vs.as_vec3().into(),
                vt: vt.as_vec3().into(),
                ds: *ds,
                dt: *dt,
            },
        }
    }

    pub fn map(&self, ctx: &TextureEvalContext) -> TexCoord2D {
        match self {
            Mapping2D::Uv { su, sv, du, dv } => TexCoord2D {
                st: Vec2::new(su * ctx.uv.x + du, sv * ctx.uv.y + dv),
                dsdx: su * ctx.dudx,
                dsdy: su * ctx.dudy,
                dtdx: sv * ctx.dvdx,
                dtdy: sv * ctx.dvdy,
            },
            Mapping2D::Spherical { texture_from_world } => {
                let TexCoord3D { p, dpdx, dpdy } = texture_space(texture_from_world, ctx);
                let x2y2 = p.x * p.x + p.y * p.y;
                let r_xy = x2y2.sqrt();
                let r2 = x2y2 + p.z * p.z;
                // s follows θ and t follows φ, as pbrt-v4 assigns them; the derivatives
                // here follow the same assignment.
                let dthetadp = Vec3A::new(p.x * p.z / r_xy, p.y * p.z / r_xy, -r_xy) / (PI * r2);
                let dphidp = Vec3A::new(-p.y, p.x, 0.0) / (TAU * x2y2);
                let v = p.normalize_or_zero();
                TexCoord2D {
                    st: Vec2::new(
                        libm::acosf(v.z.clamp(-1.0, 1.0)) / PI,
                        spherical_phi(v) / TAU,
                    ),
                    dsdx: finite(dthetadp.dot(dpdx)),
                    dsdy: finite(dthetadp.dot(dpdy)),
                    dtdx: finite(dphidp.dot(dpdx)),
                    dtdy: finite(dphidp.dot(dpdy)),
                }
            }
            Mapping2D::Cylindrical { texture_from_world } => {
                let TexCoord3D { p, dpdx, dpdy } = texture_space(texture_from_world, ctx);
                let x2y2 = p.x * p.x + p.y * p.y;
                let dsdp = Vec3A::new(-p.y, p.x, 0.0) / (TAU * x2y2);
                TexCoord2D {
                    st: Vec2::new((PI + libm::atan2f(p.y, p.x)) / TAU, p.z),
                    dsdx: finite(dsdp.dot(dpdx)),
                    dsdy: finite(dsdp.dot(dpdy)),
                    dtdx: dpdx.z,
                    dtdy: dpdy.z,
                }
            }
            Mapping2D::Planar {
                texture_from_world,
                vs,
                vt,
                ds,
                dt,
            } => {
                let TexCoord3D { p, dpdx, dpdy } = texture_space(texture_from_world, ctx);
                TexCoord2D {
                    st: Vec2::new(ds + p.dot(*vs), dt + p.dot(*vt)),
                    dsdx: vs.dot(dpdx),
                    dsdy: vs.dot(dpdy),
                    dtdx: vt.dot(dpdx),
                    dtdy: vt.dot(dpdy),
                }
            }
        }
    }
}

/// φ of a direction in [0, 2π).
pub fn spherical_phi(v: Vec3A) -> f32 {
    let p = libm::atan2f(v.y, v.x);
    if p < 0.0 { p + TAU } else { p }
}

fn finite(x: f32) -> f32 {
    if x.is_finite() { x } else { 0.0 }
}

/// The point in a solid texture's own space.
#[derive(Debug, Clone)]
pub struct Mapping3D {
    texture_from_world: Affine3A,
}

impl Mapping3D {
    pub fn new(texture_from_world: &DMat4) -> Mapping3D {
        Mapping3D {
            texture_from_world: affine(texture_from_world),
        }
    }

    pub fn map(&self, ctx: &TextureEvalContext) -> TexCoord3D {
        texture_space(&self.texture_from_world, ctx)
    }
}

/// The point of `ctx` and its footprint in a texture's own space.
fn texture_space(texture_from_world: &Affine3A, ctx: &TextureEvalContext) -> TexCoord3D {
    TexCoord3D {
        p: texture_from_world.transform_point3a(ctx.p),
        dpdx: texture_from_world.transform_vector3a(ctx.dpdx),
        dpdy: texture_from_world.transform_vector3a(ctx.dpdy),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn ctx_at(p: Vec3A, uv: Vec2) -> TextureEvalContext {
        TextureEvalContext {
            p,
            uv,
            dudx: 0.1,
            dvdy: 0.2,
            dpdx: Vec3A::new(0.01, 0.0, 0.0),
            dpdy: Vec3A::new(0.0, 0.01, 0.0),
            ..Default::default()
        }
    }

    #[test]
    fn uv_mapping_scales_and_offsets() {
        let m = Mapping2D::from_description(&Desc::Uv {
            su: 2.0,
            sv: 3.0,
            du: 0.5,
            dv: -1.0,
        });
        let c = m.map(&ctx_at(Vec3A::ZERO, Vec2::new(0.25, 0.5)));
        assert_eq!(c.st, Vec2::new(1.0, 0.5));
        assert_eq!((c.dsdx, c.dtdy), (0.2, 0.6));
    }

    #[test]
    fn spherical_mapping_gives_theta_and_phi() {
        let m = Mapping2D::from_description(&Desc::Spherical {
            texture_from_world: DMat4::from_translation(DVec3::new(-1.0, 0.0, 0.0)),
        });
        // The point (1, 2, 0) is (0, 2, 0) in texture space: θ = π/2, φ = π/2.
        let c = m.map(&ctx_at(Vec3A::new(1.0, 2.0, 0.0), Vec2::ZERO));
        assert!(
            (c.st - Vec2::new(0.5, 0.25)).abs().max_element() < 1e-6,
            "{c:?}"
        );
    }

    #[test]
    fn cylindrical_mapping_wraps_around_z() {
        let m = Mapping2D::from_description(&Desc::Cylindrical {
            texture_from_world: DMat4::IDENTITY,
        });
        let c = m.map(&ctx_at(Vec3A::new(-1.0, -1e-7, 0.75), Vec2::ZERO));
        assert!(c.st.x.abs() < 1e-6 && c.st.y == 0.75, "{c:?}");
        let c = m.map(&ctx_at(Vec3A::new(1.0, 0.0, 0.0), Vec2::ZERO));
        assert!((c.st.x - 0.5).abs() < 1e-6, "{c:?}");
    }

    #[test]
    fn planar_mapping_projects() {
        let m = Mapping2D::from_description(&Desc::Planar {
            texture_from_world: DMat4::IDENTITY,
            vs: DVec3::new(1.0, 0.0, 0.0),
            vt: DVec3::new(0.0, 0.0, 2.0),
            ds: 0.5,
            dt: 0.0,
        });
        let c = m.map(&ctx_at(Vec3A::new(1.0, 5.0, 0.25), Vec2::ZERO));
        assert_eq!(c.st, Vec2::new(1.5, 0.5));
        assert_eq!((c.dsdx, c.dsdy, c.dtdx), (0.01, 0.0, 0.0));
    }
}
