//! pbrt-v4's stochastic layered BSDF (Guo et al. 2018, as pbrt-v4 builds it): a dielectric
//! coat over a base (diffuse: "coateddiffuse"; a conductor: "coatedconductor"), with an
//! optional scattering medium of albedo `albedo` and phase asymmetry `g` between them,
//! `thickness` deep. f, pdf and sampling are Monte Carlo estimates over random walks
//! between the two interfaces, `n_samples` walks of at most `max_depth` bounces each.
//!
//! The estimates are deterministic: each seeds its random numbers from a hash of its
//! directions (and, when sampling, of its sample), so the same query gives the same answer
//! on any thread, tile or machine. Both coated materials are two-sided, as in pbrt-v4.

use super::dielectric::Lobes;
use super::{BsdfSample, ConductorBxdf, DielectricBxdf, DiffuseBxdf, same_hemisphere};
use crate::math::Color;
use crate::phase::Phase;
use glam::{Vec2, Vec3A};

/// What lies under the coat.
#[derive(Debug, Clone, Copy)]
pub enum Base<'a> {
    Diffuse(DiffuseBxdf),
    Conductor(ConductorBxdf<'a>),
}

#[derive(Debug, Clone, Copy)]
pub struct LayeredBxdf<'a> {
    pub top: DielectricBxdf,
    pub bottom: Base<'a>,
    pub thickness: f32,
    pub albedo: Color,
    pub g: f32,
    pub max_depth: u32,
    pub n_samples: u32,
}

/// One of the two interfaces, as the random walk meets them.
#[derive(Clone, Copy)]
enum Layer<'a, 'b> {
    Top(&'a DielectricBxdf),
    Bottom(&'a Base<'b>),
}

impl Layer<'_, '_> {
    fn f(self, wo: Vec3A, wi: Vec3A, importance: bool) -> Color {
        match self {
            Layer::Top(d) => d.f_mode(wo, wi, importance),
            Layer::Bottom(Base::Diffuse(d)) => d.f(wo, wi),
            Layer::Bottom(Base::Conductor(c)) => c.f(wo, wi),
        }
    }

    fn pdf(self, wo: Vec3A, wi: Vec3A, lobes: Lobes) -> f32 {
        match self {
            Layer::Top(d) => d.pdf_lobes(wo, wi, lobes),
            Layer::Bottom(_) if lobes == Lobes::Transmission => 0.0,
            Layer::Bottom(Base::Diffuse(d)) => d.pdf(wo, wi),
            Layer::Bottom(Base::Conductor(c)) => c.pdf(wo, wi),
        }
    }

    fn sample(
        self,
        wo: Vec3A,
        uc: f32,
        u: Vec2,
        lobes: Lobes,
        importance: bool,
    ) -> Option<BsdfSample> {
        let s = match self {
            Layer::Top(d) => d.sample_lobes(wo, uc, u, lobes, importance),
            Layer::Bottom(_) if lobes == Lobes::Transmission => None,
            Layer::Bottom(Base::Diffuse(d)) => d.sample(wo, uc, u),
            Layer::Bottom(Base::Conductor(c)) => c.sample(wo, uc, u),
        }?;
        (s.f != Color::ZERO && s.pdf > 0.0 && s.wi.z != 0.0).then_some(s)
    }

    fn is_specular(self) -> bool {
        match self {
            Layer::Top(d) => d.is_specular(),
            Layer::Bottom(Base::Diffuse(_)) => false,
            Layer::Bottom(Base::Conductor(c)) => c.distrib.effectively_smooth(),
        }
    }
}

/// Transmittance through the layer's medium (unit extinction) over depth `dz` along `w`.
fn tr(dz: f32, w: Vec3A) -> f32 {
    if dz.abs() <= f32::MIN_POSITIVE {
        1.0
    } else {
        libm::expf(-(dz / w.z).abs())
    }
}

fn power_heuristic(f: f32, g: f32) -> f32 {
    let (f2, g2) = (f * f, g * g);
    if f2.is_infinite() {
        1.0
    } else if f2 + g2 == 0.0 {
        0.0
    } else {
        f2 / (f2 + g2)
    }
}

/// A small deterministic generator (splitmix64) seeded from the bits of a query.
struct Rng(u64);

impl Rng {
    fn new(words: &[f32]) -> Rng {
        let mut r = Rng(0x853c_49e6_748f_ea9b);
        for w in words {
            r.0 ^= w.to_bits() as u64;
            r.next();
        }
        r
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn f(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn u2(&mut self) -> Vec2 {
        Vec2::new(self.f(), self.f())
    }
}

/// What every walk of one `f` estimate shares: the interface light leaves by and the other
/// one, the exit's depth, the direction light leaves along and the exit's sample of it,
/// and the medium's phase function.
struct Exits<'a, 'b> {
    exit: Layer<'a, 'b>,
    non_exit: Layer<'a, 'b>,
    exit_z: f32,
    wi: Vec3A,
    wis: BsdfSample,
    phase: Phase,
}

/// Where a walk is: its throughput, depth in the layer and direction.
struct Walker {
    beta: Color,
    z: f32,
    w: Vec3A,
}

impl LayeredBxdf<'_> {
    fn phase(&self) -> Phase {
        Phase::HenyeyGreenstein { g: self.g }
    }

    fn scatters(&self) -> bool {
        self.albedo != Color::ZERO
    }

    pub fn f(&self, mut wo: Vec3A, mut wi: Vec3A) -> Color {
        // Two-sided: the walk always enters through the top.
        if wo.z < 0.0 {
            wo = -wo;
            wi = -wi;
        }
        let top = Layer::Top(&self.top);
        let bottom = Layer::Bottom(&self.bottom);
        let enter = top;
        // Light leaves through the top when wi is on wo's side, else through the bottom.
        let (exit, non_exit, exit_z) = if same_hemisphere(wo, wi) {
            (top, bottom, self.thickness)
        } else {
            (bottom, top, 0.0)
        };
        let n = self.n_samples.max(1);
        let mut f = if same_hemisphere(wo, wi) {
            enter.f(wo, wi, false) * n as f32
        } else {
            Color::ZERO
        };
        let mut rng = Rng::new(&[wo.x, wo.y, wo.z, wi.x, wi.y, wi.z]);
        let phase = self.phase();
        for _ in 0..n {
            let Some(wos) = enter.sample(wo, rng.f(), rng.u2(), Lobes::Transmission, false) else {
                continue;
            };
            let Some(wis) = exit.sample(wi, rng.f(), rng.u2(), Lobes::Transmission, true) else {
                continue;
            };
            let exits = Exits {
                exit,
                non_exit,
                exit_z,
                wi,
                wis,
                phase,
            };
            self.walk(&exits, &wos, &mut rng, &mut f);
        }
        f / n as f32
    }

    /// One random walk between the interfaces from the entry sample `wos`, adding to `f`
    /// the light it carries out through the exit toward `wi`, in the order it meets it.
    fn walk(&self, x: &Exits, wos: &BsdfSample, rng: &mut Rng, f: &mut Color) {
        let mut at = Walker {
            beta: wos.f * wos.wi.z.abs() / wos.pdf,
            z: self.thickness,
            w: wos.wi,
        };
        for depth in 0..self.max_depth {
            if depth > 3 && at.beta.max_element() < 0.25 {
                let q = (1.0 - at.beta.max_element()).max(0.0);
                if rng.f() < q {
                    break;
                }
                at.beta /= 1.0 - q;
            }
            if !self.scatters() {
                at.z = if at.z == self.thickness {
                    0.0
                } else {
                    self.thickness
                };
                at.beta *= tr(self.thickness, at.w);
            } else {
                let dz = -libm::logf(1.0 - rng.f()) * at.w.z.abs();
                let zp = if at.w.z > 0.0 { at.z + dz } else { at.z - dz };
                if zp == at.z {
                    continue;
                }
                if 0.0 < zp && zp < self.thickness {
                    self.scatter_inside(x, zp, rng, &mut at, f);
                    continue;
                }
                at.z = zp.clamp(0.0, self.thickness);
            }
            let reflected = if at.z == x.exit_z {
                // Reflection off the exit interface, back into the layer.
                x.exit
                    .sample(-at.w, rng.f(), rng.u2(), Lobes::Reflection, false)
                    .map(|bs| {
                        at.beta *= bs.f * bs.wi.z.abs() / bs.pdf;
                        at.w = bs.wi;
                    })
            } else {
                self.reflect_off_non_exit(x, rng, &mut at, f)
            };
            if reflected.is_none() {
                break;
            }
        }
    }

    /// Scattering inside the layer at depth `zp`: light leaving through the exit toward wi,
    /// by MIS between the phase function and the exit's sampled direction, then the phase
    /// function's new direction (and, by it, light leaving through the exit).
    fn scatter_inside(&self, x: &Exits, zp: f32, rng: &mut Rng, at: &mut Walker, f: &mut Color) {
        let (exit, wis, phase) = (x.exit, &x.wis, x.phase);
        let wt = if exit.is_specular() {
            1.0
        } else {
            power_heuristic(wis.pdf, phase.p(-at.w, -wis.wi))
        };
        *f += at.beta
            * self.albedo
            * phase.p(-at.w, -wis.wi)
            * wt
            * tr(zp - x.exit_z, wis.wi)
            * wis.f
            / wis.pdf;
        let (pw, ppdf) = phase.sample(-at.w, rng.u2());
        if ppdf == 0.0 || pw.z == 0.0 {
            return;
        }
        // Sampled exactly: p / pdf = 1.
        at.beta *= self.albedo;
        at.w = pw;
        at.z = zp;
        if ((at.z < x.exit_z && at.w.z > 0.0) || (at.z > x.exit_z && at.w.z < 0.0))
            && !exit.is_specular()
        {
            let f_exit = exit.f(-at.w, x.wi, false);
            if f_exit != Color::ZERO {
                let exit_pdf = exit.pdf(x.wi, -at.w, Lobes::Transmission);
                let wt = power_heuristic(ppdf, exit_pdf);
                *f += at.beta * tr(zp - x.exit_z, pw) * f_exit * wt;
            }
        }
    }

    /// At the interface the light does not leave by: light that reflects there and
    /// leaves, then the walk's reflection off it (None: the walk ends).
    fn reflect_off_non_exit(
        &self,
        x: &Exits,
        rng: &mut Rng,
        at: &mut Walker,
        f: &mut Color,
    ) -> Option<()> {
        let (exit, non_exit, wis) = (x.exit, x.non_exit, &x.wis);
        if !non_exit.is_specular() {
            let wt = if exit.is_specular() {
                1.0
            } else {
                power_heuristic(wis.pdf, non_exit.pdf(-at.w, -wis.wi, Lobes::All))
            };
            *f += at.beta
                * non_exit.f(-at.w, -wis.wi, false)
                * wis.wi.z.abs()
                * wt
                * tr(self.thickness, wis.wi)
                * wis.f
                / wis.pdf;
        }
        let bs = non_exit.sample(-at.w, rng.f(), rng.u2(), Lobes::Reflection, false)?;
        at.beta *= bs.f * bs.wi.z.abs() / bs.pdf;
        at.w = bs.wi;
        if !exit.is_specular() {
            let f_exit = exit.f(-at.w, x.wi, false);
            if f_exit != Color::ZERO {
                let wt = if non_exit.is_specular() {
                    1.0
                } else {
                    power_heuristic(bs.pdf, exit.pdf(x.wi, -at.w, Lobes::Transmission))
                };
                *f += at.beta * tr(self.thickness, bs.wi) * f_exit * wt;
            }
        }
        Some(())
    }

    /// A direction by a random walk through the layers; `f` and `pdf` are those of the
    /// walk (their ratio is right; the pdf alone is only proportional to the true one).
    pub fn sample_walk(&self, mut wo: Vec3A, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let flip = wo.z < 0.0;
        if flip {
            wo = -wo;
        }
        let top = Layer::Top(&self.top);
        let bottom = Layer::Bottom(&self.bottom);
        let bs = top.sample(wo, uc, u, Lobes::All, false)?;
        if same_hemisphere(wo, bs.wi) {
            let wi = if flip { -bs.wi } else { bs.wi };
            return Some(BsdfSample { wi, ..bs });
        }
        let mut w = bs.wi;
        let mut specular = bs.specular;
        let mut rng = Rng::new(&[wo.x, wo.y, wo.z, uc, u.x, u.y]);
        let mut f = bs.f * bs.wi.z.abs();
        let mut pdf = bs.pdf;
        let mut z = self.thickness;
        let phase = self.phase();
        for depth in 0..self.max_depth {
            let rr = f.max_element() / pdf;
            if depth > 3 && rr < 0.25 {
                let q = (1.0 - rr).max(0.0);
                if rng.f() < q {
                    return None;
                }
                pdf *= 1.0 - q;
            }
            if w.z == 0.0 {
                return None;
            }
            if self.scatters() {
                let dz = -libm::logf(1.0 - rng.f()) * w.z.abs();
                let zp = if w.z > 0.0 { z + dz } else { z - dz };
                if zp == z {
                    return None;
                }
                if 0.0 < zp && zp < self.thickness {
                    let (pw, ppdf) = phase.sample(-w, rng.u2());
                    if ppdf == 0.0 || pw.z == 0.0 {
                        return None;
                    }
                    f *= self.albedo * ppdf;
                    pdf *= ppdf;
                    specular = false;
                    w = pw;
                    z = zp;
                    continue;
                }
                z = zp.clamp(0.0, self.thickness);
            } else {
                z = if z == self.thickness {
                    0.0
                } else {
                    self.thickness
                };
                f *= tr(self.thickness, w);
            }
            let layer = if z == 0.0 { bottom } else { top };
            let bs = layer.sample(-w, rng.f(), rng.u2(), Lobes::All, false)?;
            let transmitted = !same_hemisphere(-w, bs.wi);
            f *= bs.f;
            pdf *= bs.pdf;
            specular &= bs.specular;
            w = bs.wi;
            if transmitted {
                // Out through the coat (the bases transmit nothing).
                let wi = if flip { -w } else { w };
                return Some(BsdfSample {
                    f,
                    wi,
                    pdf,
                    specular,
                    eta: 1.0,
                });
            }
            f *= bs.wi.z.abs();
        }
        None
    }

    pub fn pdf(&self, mut wo: Vec3A, mut wi: Vec3A) -> f32 {
        if wo.z < 0.0 {
            wo = -wo;
            wi = -wi;
        }
        let top = Layer::Top(&self.top);
        let bottom = Layer::Bottom(&self.bottom);
        let mut rng = Rng::new(&[wi.x, wi.y, wi.z, wo.x, wo.y, wo.z]);
        let n = self.n_samples.max(1);
        let mut sum = 0.0;
        if same_hemisphere(wo, wi) {
            sum += n as f32 * top.pdf(wo, wi, Lobes::Reflection);
        }
        for _ in 0..n {
            if same_hemisphere(wo, wi) {
                let (r_layer, t_layer) = (bottom, top);
                let wos = t_layer.sample(wo, rng.f(), rng.u2(), Lobes::Transmission, false);
                let wis = t_layer.sample(wi, rng.f(), rng.u2(), Lobes::Transmission, true);
                if let (Some(wos), Some(wis)) = (wos, wis) {
                    if t_layer.is_specular() {
                        sum += r_layer.pdf(-wos.wi, -wis.wi, Lobes::All);
                    } else if let Some(rs) =
                        r_layer.sample(-wos.wi, rng.f(), rng.u2(), Lobes::All, false)
                    {
                        if r_layer.is_specular() {
                            sum += t_layer.pdf(-rs.wi, wi, Lobes::All);
                        } else {
                            let r_pdf = r_layer.pdf(-wos.wi, -wis.wi, Lobes::All);
                            sum += power_heuristic(wis.pdf, r_pdf) * r_pdf;
                            let t_pdf = t_layer.pdf(-rs.wi, wi, Lobes::All);
                            sum += power_heuristic(rs.pdf, t_pdf) * t_pdf;
                        }
                    }
                }
            }
            // (Transmission through both interfaces cannot happen over an opaque base.)
        }
        // Mix with a uniform pdf, as pbrt-v4 does, so that no direction the walk can reach
        // has a zero density.
        let uniform = 1.0 / (4.0 * std::f32::consts::PI);
        0.1 * uniform + 0.9 * sum / n as f32
    }

    /// Sampled from a delta lobe only when the coat and the base are both smooth and the
    /// layer does not scatter.
    pub fn is_specular(&self) -> bool {
        false
    }
}
