//! Participating media and phase functions.

use crate::math::{Color, Frame, Ray};
use glam::{Affine3A, Vec2, Vec3A};
use std::f32::consts::PI;

/// A medium: what fills the space between surfaces.
#[derive(Debug, Clone)]
pub enum Medium {
    /// Constant absorption and scattering per unit length, emission `le` (pbrt-v4's convention:
    /// the source term is sigma_a * le).
    Homogeneous {
        sigma_a: Color,
        sigma_s: Color,
        le: Color,
        phase: Phase,
    },
    /// Coefficients scaled by a density grid, with optional emission (a heterogeneous medium).
    Grid(Box<GridMedium>),
}

impl Medium {
    /// A homogeneous medium's extinction (zero for a grid, whose extinction varies).
    pub fn sigma_t(&self) -> Color {
        match self {
            Medium::Homogeneous {
                sigma_a, sigma_s, ..
            } => *sigma_a + *sigma_s,
            Medium::Grid(_) => Color::ZERO,
        }
    }

    /// Transmittance of a homogeneous medium along a straight segment of length `t`.
    pub fn transmittance(&self, t: f32) -> Color {
        if !t.is_finite() {
            return Color::select(self.sigma_t().cmpgt(Color::ZERO), Color::ZERO, Color::ONE);
        }
        (-self.sigma_t() * t).exp()
    }

    /// The emission a homogeneous segment of length `t` sends back to its start: the integral
    /// of T(s) sigma_a le ds, in closed form. (A grid's emission is estimated while tracking.)
    pub fn segment_emission(&self, t: f32) -> Color {
        let Medium::Homogeneous { sigma_a, le, .. } = self else {
            return Color::ZERO;
        };
        if *le == Color::ZERO || *sigma_a == Color::ZERO {
            return Color::ZERO;
        }
        let st = self.sigma_t();
        let mut out = Color::ZERO;
        for c in 0..3 {
            out[c] = if st[c] > 0.0 {
                // (1 - exp(-st t)) / st, written to stay accurate for small st t.
                let x = st[c] * t.min(1e30);
                sigma_a[c] * le[c] * (-(-x).exp_m1()) / st[c]
            } else {
                0.0
            };
        }
        out
    }

    pub fn phase(&self) -> Phase {
        match self {
            Medium::Homogeneous { phase, .. } => *phase,
            Medium::Grid(g) => g.phase,
        }
    }
}

/// What free-flight sampling through a medium segment found.
pub enum MediumEvent {
    /// The segment was crossed: the ray reaches its surface (or escapes).
    Crossed,
    /// Absorbed: the path ends.
    Absorbed,
    /// Scattered at this distance along the ray.
    Scattered(f32),
}

impl Medium {
    /// Free-flight sampling along `ray` over (0, `t_max`), updating the throughput `beta`.
    /// In an emissive grid, `emission(t, sigma_maj, beta * sigma_a * Le)` is called at each
    /// tentative collision before the event there is chosen (the caller weights it and
    /// divides by sigma_maj); a homogeneous medium's emission is the caller's, in closed form
    /// (`segment_emission`). The path tracer and the photon tracer share this.
    pub fn sample_interaction(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut TrackingRng,
        beta: &mut Color,
        emission: impl FnMut(f32, f32, Color),
    ) -> MediumEvent {
        match self {
            Medium::Grid(g) => g.track(ray, t_max, rng, beta, emission),
            Medium::Homogeneous { sigma_s, .. } => {
                homogeneous_track(self.sigma_t(), *sigma_s, t_max, rng, beta)
            }
        }
    }
}

/// Free-flight sampling in a homogeneous medium: a colour channel is chosen uniformly and
/// the distance sampled by its extinction; the weights divide by the density averaged over
/// channels (the one-sample balance heuristic, as pbrt-v3's homogeneous medium does), so
/// they stay bounded even when the channels' extinctions differ.
fn homogeneous_track(
    sigma_t: Color,
    sigma_s: Color,
    t_max: f32,
    rng: &mut TrackingRng,
    beta: &mut Color,
) -> MediumEvent {
    if sigma_t.max_element() <= 0.0 {
        return MediumEvent::Crossed;
    }
    let channel = ((rng.next_f32() * 3.0) as usize).min(2);
    let st = sigma_t[channel];
    let t = if st > 0.0 {
        -(1.0 - rng.next_f32()).ln() / st
    } else {
        f32::INFINITY
    };
    if t < t_max {
        let tr = (-sigma_t * t).exp();
        let density = (sigma_t * tr).element_sum() / 3.0;
        if density <= 0.0 {
            return MediumEvent::Absorbed;
        }
        *beta *= sigma_s * tr / density;
        if *beta == Color::ZERO {
            return MediumEvent::Absorbed;
        }
        MediumEvent::Scattered(t)
    } else {
        if !t_max.is_finite() {
            return MediumEvent::Absorbed;
        }
        let tr = (-sigma_t * t_max).exp();
        let p_cross = tr.element_sum() / 3.0;
        if p_cross <= 0.0 {
            return MediumEvent::Absorbed;
        }
        *beta *= tr / p_cross;
        MediumEvent::Crossed
    }
}

/// A phase function; `wo` and `wi` both point away from the scattering point, and both kinds
/// are sampled exactly (the value over the pdf is 1).
#[derive(Debug, Clone, Copy)]
pub enum Phase {
    HenyeyGreenstein {
        g: f32,
    },
    /// Schlick's rational approximation of Henyey-Greenstein, with k from g (Blasi et al.).
    Schlick {
        k: f32,
    },
}

impl Phase {
    pub fn new(desc: kiln_scene::PhaseDesc) -> Phase {
        match desc {
            kiln_scene::PhaseDesc::HenyeyGreenstein { g } => Phase::HenyeyGreenstein { g },
            kiln_scene::PhaseDesc::Schlick { g } => Phase::Schlick {
                k: (1.55 * g - 0.55 * g * g * g).clamp(-0.999, 0.999),
            },
        }
    }

    /// Density over `wi` given `wo`.
    pub fn p(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        // The cosine between the directions of travel before and after scattering.
        let c = -wo.dot(wi);
        match *self {
            Phase::HenyeyGreenstein { g } => {
                let denom = 1.0 + g * g - 2.0 * g * c;
                (1.0 - g * g) / (4.0 * PI * denom * denom.max(1e-12).sqrt())
            }
            Phase::Schlick { k } => {
                let d = 1.0 - k * c;
                (1.0 - k * k) / (4.0 * PI * d * d)
            }
        }
    }

    /// Samples `wi`; returns it with its pdf.
    pub fn sample(&self, wo: Vec3A, u: Vec2) -> (Vec3A, f32) {
        // The cosine between the directions of travel, inverted from the CDF.
        let c = match *self {
            Phase::HenyeyGreenstein { g } => {
                if g.abs() < 1e-3 {
                    2.0 * u.x - 1.0
                } else {
                    let sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
                    (1.0 + g * g - sq * sq) / (2.0 * g)
                }
            }
            Phase::Schlick { k } => (2.0 * u.x + k - 1.0) / (2.0 * k * u.x + 1.0 - k),
        }
        .clamp(-1.0, 1.0);
        let sin = (1.0 - c * c).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let frame = Frame::from_z(-wo);
        let wi = frame.to_world(Vec3A::new(sin * phi.cos(), sin * phi.sin(), c));
        (wi, self.p(wo, wi))
    }
}

/// A small deterministic generator for the unbounded number of random numbers that
/// tracking may need, seeded from the path's sampler (so still a pure function of
/// pixel, sample and dimension).
pub struct TrackingRng(u64);

impl TrackingRng {
    pub fn new(seed: u64) -> TrackingRng {
        TrackingRng(seed)
    }

    /// Seeded from sample values already drawn (their bits), with a stream number.
    pub fn from_values(values: &[f32], stream: u32) -> TrackingRng {
        let mut seed = 0x243f_6a88_85a3_08d3u64 ^ u64::from(stream);
        for v in values {
            seed = (seed ^ u64::from(v.to_bits())).wrapping_mul(0x1000_0000_01b3);
            seed ^= seed >> 29;
        }
        TrackingRng(seed)
    }

    pub fn next_f32(&mut self) -> f32 {
        // SplitMix64.
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A scalar grid looked up as pbrt-v4's `SampledGrid`: sample (i, j, k) at the centre of
/// voxel (i, j, k) of the unit box, trilinear in between, zero outside the samples.
#[derive(Debug, Clone)]
pub struct SampledGrid {
    n: [usize; 3],
    values: Vec<f32>,
}

impl SampledGrid {
    pub fn new(g: &kiln_scene::VoxelGrid) -> SampledGrid {
        SampledGrid {
            n: [g.nx, g.ny, g.nz],
            values: g.values.clone(),
        }
    }

    fn at(&self, x: i64, y: i64, z: i64) -> f32 {
        let [nx, ny, nz] = self.n.map(|v| v as i64);
        if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
            return 0.0;
        }
        self.values[((z * ny + y) * nx + x) as usize]
    }

    /// The value at `p` in the unit box.
    pub fn lookup(&self, p: Vec3A) -> f32 {
        let s = p * Vec3A::new(self.n[0] as f32, self.n[1] as f32, self.n[2] as f32) - 0.5;
        let f = s.floor();
        let d = s - f;
        let (x, y, z) = (f.x as i64, f.y as i64, f.z as i64);
        let lerp = |t: f32, a: f32, b: f32| a + t * (b - a);
        let [nx, ny, nz] = self.n.map(|v| v as i64);
        if x >= 0 && y >= 0 && z >= 0 && x + 1 < nx && y + 1 < ny && z + 1 < nz {
            // All eight samples inside: one index computation, no per-sample checks.
            let (sy, sz) = (nx as usize, (nx * ny) as usize);
            let i = ((z * ny + y) * nx + x) as usize;
            let v = &self.values[i..i + sz + sy + 2];
            let c00 = lerp(d.x, v[0], v[1]);
            let c10 = lerp(d.x, v[sy], v[sy + 1]);
            let c01 = lerp(d.x, v[sz], v[sz + 1]);
            let c11 = lerp(d.x, v[sz + sy], v[sz + sy + 1]);
            return lerp(d.z, lerp(d.y, c00, c10), lerp(d.y, c01, c11));
        }
        let c00 = lerp(d.x, self.at(x, y, z), self.at(x + 1, y, z));
        let c10 = lerp(d.x, self.at(x, y + 1, z), self.at(x + 1, y + 1, z));
        let c01 = lerp(d.x, self.at(x, y, z + 1), self.at(x + 1, y, z + 1));
        let c11 = lerp(d.x, self.at(x, y + 1, z + 1), self.at(x + 1, y + 1, z + 1));
        lerp(d.z, lerp(d.y, c00, c10), lerp(d.y, c01, c11))
    }

    /// An upper bound of the value over the box `lo`..`hi` of the unit box: the largest
    /// sample whose interpolation reaches into it.
    pub fn max_over(&self, lo: Vec3A, hi: Vec3A) -> f32 {
        let range = |a: usize| {
            let n = self.n[a] as f32;
            let i0 = ((lo[a] * n - 0.5).floor().max(0.0)) as usize;
            let i1 = ((hi[a] * n - 0.5).floor() + 1.0).clamp(0.0, n - 1.0) as usize;
            i0.min(self.n[a] - 1)..=i1
        };
        let mut m = 0.0f32;
        for z in range(2) {
            for y in range(1) {
                for x in range(0) {
                    m = m.max(self.values[(z * self.n[1] + y) * self.n[0] + x]);
                }
            }
        }
        m
    }

    pub fn max(&self) -> f32 {
        self.values.iter().copied().fold(0.0, f32::max)
    }
}

/// Where a grid medium's emitted radiance comes from.
#[derive(Debug, Clone)]
enum Emission {
    Constant(Color),
    /// Temperature, then (T - offset) * t_scale through a table of the peak-normalised
    /// blackbody.
    Temperature {
        grid: SampledGrid,
        offset: f32,
        t_scale: f32,
        table: BlackbodyTable,
    },
}

/// The peak-normalised blackbody's RGB from 100 K to the hottest temperature a grid holds,
/// tabulated: converting a spectrum per lookup would cost a thousand times more.
#[derive(Debug, Clone)]
struct BlackbodyTable {
    t_max: f32,
    step: f32,
    rgb: Vec<Color>,
}

const BLACKBODY_MIN_K: f32 = 100.0;

impl BlackbodyTable {
    fn new(t_max: f32) -> BlackbodyTable {
        let n = 2048usize;
        let t_max = t_max.max(BLACKBODY_MIN_K * 2.0);
        let step = (t_max - BLACKBODY_MIN_K) / (n - 1) as f32;
        let rgb = (0..n)
            .map(|i| {
                crate::math::rgb(kiln_scene::spectrum::blackbody_peak_rgb(
                    BLACKBODY_MIN_K + step * i as f32,
                ))
            })
            .collect();
        BlackbodyTable { t_max, step, rgb }
    }

    fn at(&self, kelvin: f32) -> Color {
        if kelvin <= BLACKBODY_MIN_K {
            return Color::ZERO;
        }
        let x = (kelvin.min(self.t_max) - BLACKBODY_MIN_K) / self.step;
        let i = (x as usize).min(self.rgb.len() - 2);
        let f = x - i as f32;
        self.rgb[i] * (1.0 - f) + self.rgb[i + 1] * f
    }
}

/// Cells of the majorant grid along each axis (pbrt-v4 uses 16 too).
const MAJORANT_RES: usize = 16;

/// A heterogeneous medium: pbrt-v4's "uniformgrid". Tracking runs against a coarse grid of
/// majorants (the largest density each cell can hold), walked cell by cell with a 3D DDA.
#[derive(Debug, Clone)]
pub struct GridMedium {
    /// Per unit density.
    pub sigma_a: Color,
    pub sigma_s: Color,
    pub phase: Phase,
    density: SampledGrid,
    emission: Option<(Emission, SampledGrid)>,
    /// World space to the unit box, and to majorant cells ([0, MAJORANT_RES]^3).
    world_to_box: Affine3A,
    box_to_world: Affine3A,
    majorant: Vec<f32>,
    /// The largest channel of sigma_a + sigma_s.
    sigma_t_max: f32,
    /// World-space volume of the box.
    box_volume: f32,
    /// The distribution of emitted luminance over voxels, for sampling it as a light.
    pub emission_distribution: Option<Distribution3D>,
}

impl GridMedium {
    pub fn new(desc: &kiln_scene::GridMediumDesc) -> GridMedium {
        let p0 = Vec3A::from(desc.p0);
        let p1 = Vec3A::from(desc.p1);
        let medium_to_world = Affine3A::from_mat4(desc.medium_to_world.as_mat4());
        let box_to_medium =
            Affine3A::from_translation((p0).into()) * Affine3A::from_scale((p1 - p0).into());
        let box_to_world = medium_to_world * box_to_medium;
        let world_to_box = box_to_world.inverse();
        let density = SampledGrid::new(&desc.density);
        let emission = match &desc.emission {
            kiln_scene::GridEmission::None => None,
            kiln_scene::GridEmission::Constant { le, scale } => Some((
                Emission::Constant(crate::math::rgb(*le)),
                SampledGrid::new(scale),
            )),
            kiln_scene::GridEmission::Temperature {
                temperature,
                offset,
                t_scale,
                scale,
            } => {
                let grid = SampledGrid::new(temperature);
                let t_max = (grid.max() - offset) * t_scale;
                Some((
                    Emission::Temperature {
                        grid,
                        offset: *offset,
                        t_scale: *t_scale,
                        table: BlackbodyTable::new(t_max.max(0.0)),
                    },
                    SampledGrid::new(scale),
                ))
            }
        };
        let r = MAJORANT_RES;
        let mut majorant = vec![0.0; r * r * r];
        for z in 0..r {
            for y in 0..r {
                for x in 0..r {
                    let lo = Vec3A::new(x as f32, y as f32, z as f32) / r as f32;
                    let hi = lo + Vec3A::splat(1.0 / r as f32);
                    majorant[(z * r + y) * r + x] = density.max_over(lo, hi);
                }
            }
        }
        let sigma_t = crate::math::rgb(desc.sigma_a) + crate::math::rgb(desc.sigma_s);
        let mut m = GridMedium {
            sigma_a: crate::math::rgb(desc.sigma_a),
            sigma_s: crate::math::rgb(desc.sigma_s),
            phase: Phase::new(desc.phase),
            density,
            emission,
            world_to_box,
            box_to_world,
            majorant,
            sigma_t_max: sigma_t.max_element(),
            box_volume: box_to_world.matrix3.determinant().abs(),
            emission_distribution: None,
        };
        m.emission_distribution = m.build_distribution();
        m
    }

    /// Density at `p` in the unit box.
    pub fn density(&self, p: Vec3A) -> f32 {
        self.density.lookup(p)
    }

    pub fn is_emissive(&self) -> bool {
        self.emission.is_some() && self.sigma_a.max_element() > 0.0
    }

    /// Emitted radiance Le at `p` in the unit box (the source term is sigma_a * density * Le).
    pub fn le(&self, p: Vec3A) -> Color {
        let Some((emission, scale)) = &self.emission else {
            return Color::ZERO;
        };
        let s = scale.lookup(p);
        if s <= 0.0 {
            return Color::ZERO;
        }
        match emission {
            Emission::Constant(le) => *le * s,
            Emission::Temperature {
                grid,
                offset,
                t_scale,
                table,
            } => table.at((grid.lookup(p) - offset) * t_scale) * s,
        }
    }

    /// The source term sigma_a * Le at `p` in the unit box.
    pub fn source(&self, p: Vec3A) -> Color {
        if self.emission.is_none() {
            return Color::ZERO;
        }
        let d = self.density(p);
        if d <= 0.0 {
            return Color::ZERO;
        }
        self.sigma_a * d * self.le(p)
    }

    pub fn to_box(&self, world: Vec3A) -> Vec3A {
        self.world_to_box.transform_point3a(world)
    }

    /// The majorant (tentative collisions per unit length) at `p` in the unit box.
    pub fn majorant_at(&self, p: Vec3A) -> f32 {
        if p.min_element() < 0.0 || p.max_element() > 1.0 {
            return 0.0;
        }
        let r = MAJORANT_RES;
        let c = (p * r as f32)
            .as_uvec3()
            .min(glam::UVec3::splat(r as u32 - 1));
        self.sigma_t_max * self.majorant[(c.z as usize * r + c.y as usize) * r + c.x as usize]
    }

    /// Visits the tentative collisions along the ray from `o` in unit direction `d` over
    /// (0, t_max): a Poisson process whose rate is the majorant of the cell the point is in.
    /// `visit(t, p_box, sigma_maj)` returns false to stop; the walk returns whether it ran to
    /// the end.
    pub fn walk(
        &self,
        o: Vec3A,
        d: Vec3A,
        t_max: f32,
        rng: &mut TrackingRng,
        mut visit: impl FnMut(f32, Vec3A, f32) -> bool,
    ) -> bool {
        let r = MAJORANT_RES as f32;
        let oc = self.world_to_box.transform_point3a(o) * r;
        let dc = self.world_to_box.transform_vector3a(d) * r;
        // Clip to the box [0, r]^3.
        let (mut t, mut t_end) = (0.0f32, t_max);
        for a in 0..3 {
            if dc[a] == 0.0 {
                if oc[a] < 0.0 || oc[a] > r {
                    return true;
                }
                continue;
            }
            let inv = 1.0 / dc[a];
            let (mut ta, mut tb) = (-oc[a] * inv, (r - oc[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t = t.max(ta);
            t_end = t_end.min(tb);
        }
        if t.partial_cmp(&t_end) != Some(std::cmp::Ordering::Less) {
            return true;
        }
        let p = oc + dc * t;
        let n = MAJORANT_RES as i32;
        let mut cell = [0i32; 3];
        let mut next = [f32::INFINITY; 3];
        let mut delta = [f32::INFINITY; 3];
        let mut step = [0i32; 3];
        for a in 0..3 {
            cell[a] = (p[a].floor() as i32).clamp(0, n - 1);
            if dc[a] > 0.0 {
                next[a] = t + ((cell[a] + 1) as f32 - p[a]) / dc[a];
                delta[a] = 1.0 / dc[a];
                step[a] = 1;
            } else if dc[a] < 0.0 {
                next[a] = t + (cell[a] as f32 - p[a]) / dc[a];
                delta[a] = -1.0 / dc[a];
                step[a] = -1;
            }
        }
        // Optical depth left before the next tentative collision.
        let mut tau = -(1.0 - rng.next_f32()).ln();
        loop {
            let axis = if next[0] < next[1] {
                if next[0] < next[2] { 0 } else { 2 }
            } else if next[1] < next[2] {
                1
            } else {
                2
            };
            let t_exit = next[axis].min(t_end);
            let idx = ((cell[2] * n + cell[1]) * n + cell[0]) as usize;
            let sigma_maj = self.sigma_t_max * self.majorant[idx];
            if sigma_maj > 0.0 {
                loop {
                    let dt = tau / sigma_maj;
                    if t + dt >= t_exit {
                        tau -= sigma_maj * (t_exit - t);
                        break;
                    }
                    t += dt;
                    tau = -(1.0 - rng.next_f32()).ln();
                    if !visit(t, (oc + dc * t) / r, sigma_maj) {
                        return false;
                    }
                }
            }
            t = t_exit;
            if t >= t_end {
                return true;
            }
            cell[axis] += step[axis];
            if cell[axis] < 0 || cell[axis] >= n {
                return true;
            }
            next[axis] += delta[axis];
        }
    }

    /// Transmittance along the ray over (0, t_max) by ratio tracking, with Russian roulette
    /// once it is small. Returns it with the number of density lookups.
    pub fn transmittance(&self, o: Vec3A, d: Vec3A, t_max: f32, rng: &mut TrackingRng) -> Color {
        let mut tr = Color::ONE;
        let sigma_t = self.sigma_a + self.sigma_s;
        let mut u = TrackingRng::new(rng.0 ^ 0x5851_f42d_4c95_7f2d);
        self.walk(o, d, t_max, rng, |_, p, sigma_maj| {
            let st = sigma_t * self.density(p);
            tr *= (Color::ONE - st / sigma_maj).max(Color::ZERO);
            if tr.max_element() < 0.05 {
                if u.next_f32() < 0.75 {
                    tr = Color::ZERO;
                } else {
                    tr /= 0.25;
                }
            }
            tr != Color::ZERO
        });
        tr
    }

    /// Tracking against the majorants: at each tentative collision the emission is handed
    /// to `emission` (see [`Medium::sample_interaction`]), then absorption, scattering or a
    /// null collision is chosen with probabilities from the channel-averaged coefficients.
    /// The weights sigma_x / (sigma_maj P_x) keep the estimate unbiased for coloured media
    /// (and are exactly 1 for grey ones: plain delta tracking).
    fn track(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut TrackingRng,
        beta: &mut Color,
        mut emission: impl FnMut(f32, f32, Color),
    ) -> MediumEvent {
        let mut event = MediumEvent::Crossed;
        let mut choice = TrackingRng::new(rng.next_f32().to_bits() as u64 ^ 0x6a09_e667_f3bc_c909);
        let emissive = self.is_emissive();
        self.walk(ray.origin, ray.dir, t_max, rng, |t, p, sigma_maj| {
            let d = self.density(p);
            if d <= 0.0 {
                return true;
            }
            let sigma_a = self.sigma_a * d;
            let sigma_s = self.sigma_s * d;
            if emissive {
                let le = self.le(p);
                if le != Color::ZERO {
                    emission(t, sigma_maj, *beta * sigma_a * le);
                }
            }
            let p_a = sigma_a.element_sum() / (3.0 * sigma_maj);
            let p_s = sigma_s.element_sum() / (3.0 * sigma_maj);
            let xi = choice.next_f32();
            if xi < p_a {
                event = MediumEvent::Absorbed;
                return false;
            }
            if xi < p_a + p_s {
                *beta *= sigma_s / (sigma_maj * p_s);
                event = MediumEvent::Scattered(t);
                return false;
            }
            let p_n = 1.0 - p_a - p_s;
            if p_n <= 0.0 {
                event = MediumEvent::Absorbed;
                return false;
            }
            let sigma_n = (Color::splat(sigma_maj) - sigma_a - sigma_s).max(Color::ZERO);
            *beta *= sigma_n / (sigma_maj * p_n);
            *beta != Color::ZERO
        });
        if *beta == Color::ZERO {
            return MediumEvent::Absorbed;
        }
        event
    }

    /// Builds the 3D distribution of emitted luminance: each voxel's weight is the source
    /// term's luminance averaged over its centre and its eight corners (the corners are the
    /// centres of the interpolation cells it overlaps, so a voxel whose emission is anywhere
    /// non-zero gets a non-zero weight).
    fn build_distribution(&self) -> Option<Distribution3D> {
        if !self.is_emissive() {
            return None;
        }
        let [nx, ny, nz] = self.density.n;
        let size = Vec3A::new(nx as f32, ny as f32, nz as f32);
        let lum = |p: Vec3A| crate::math::luminance(self.source(p)).max(0.0);
        let corner_index = |x: usize, y: usize, z: usize| (z * (ny + 1) + y) * (nx + 1) + x;
        let mut corners = vec![0.0f32; (nx + 1) * (ny + 1) * (nz + 1)];
        for z in 0..=nz {
            for y in 0..=ny {
                for x in 0..=nx {
                    corners[corner_index(x, y, z)] =
                        lum(Vec3A::new(x as f32, y as f32, z as f32) / size);
                }
            }
        }
        let mut weights = vec![0.0f32; nx * ny * nz];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let mut sum = lum((Vec3A::new(x as f32, y as f32, z as f32) + 0.5) / size);
                    for c in 0..8 {
                        sum += corners[corner_index(x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2))];
                    }
                    weights[(z * ny + y) * nx + x] = sum / 9.0;
                }
            }
        }
        let dist = Distribution3D::new(weights, [nx, ny, nz]);
        (dist.total > 0.0).then_some(dist)
    }

    /// Emitted power (luminance) for choosing among lights: 4 pi times the source term
    /// integrated over the box, as the distribution's weights estimate it (self-absorption
    /// is ignored).
    pub fn emitted_power(&self) -> f32 {
        self.emission_distribution.as_ref().map_or(0.0, |d| {
            let voxels = (d.n[0] * d.n[1] * d.n[2]) as f64;
            (4.0 * std::f64::consts::PI * d.total * self.box_volume as f64 / voxels) as f32
        })
    }

    /// Samples a point by the emission distribution: returns it in world space with its pdf
    /// per unit world volume.
    pub fn sample_emission(&self, u: [f32; 3], rng: &mut TrackingRng) -> Option<(Vec3A, f32)> {
        let dist = self.emission_distribution.as_ref()?;
        let (voxel, pmf) = dist.sample(u);
        let offset = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let n = Vec3A::new(dist.n[0] as f32, dist.n[1] as f32, dist.n[2] as f32);
        let p_box = (Vec3A::new(voxel[0] as f32, voxel[1] as f32, voxel[2] as f32) + offset) / n;
        let p = self.box_to_world.transform_point3a(p_box);
        Some((p, pmf * (n.x * n.y * n.z) / self.box_volume))
    }

    /// The density per unit world volume with which [`GridMedium::sample_emission`] returns
    /// the world point `p`.
    pub fn emission_pdf(&self, p: Vec3A) -> f32 {
        let Some(dist) = &self.emission_distribution else {
            return 0.0;
        };
        let b = self.to_box(p);
        if b.min_element() < 0.0 || b.max_element() >= 1.0 {
            return 0.0;
        }
        let v = [0, 1, 2].map(|a| ((b[a] * dist.n[a] as f32) as usize).min(dist.n[a] - 1));
        dist.pmf(v) * (dist.n[0] * dist.n[1] * dist.n[2]) as f32 / self.box_volume
    }
}

/// A discrete distribution over the voxels of a grid, sampled as p(x) p(y | x) p(z | x, y)
/// (seed 001): a marginal over x, a conditional over y for each x, a conditional over z for
/// each (x, y), each a cumulative table searched by bisection.
#[derive(Debug, Clone)]
pub struct Distribution3D {
    pub n: [usize; 3],
    weights: Vec<f32>,
    /// Sum of the weights (f64: millions of them).
    pub total: f64,
    /// Cumulative sums, each table starting at 0: x (nx + 1), y per x, z per (x, y).
    cdf_x: Vec<f64>,
    cdf_y: Vec<f64>,
    cdf_z: Vec<f64>,
}

impl Distribution3D {
    /// `weights[(z * ny + y) * nx + x]`, non-negative.
    pub fn new(weights: Vec<f32>, n: [usize; 3]) -> Distribution3D {
        let [nx, ny, nz] = n;
        let w = |x: usize, y: usize, z: usize| f64::from(weights[(z * ny + y) * nx + x]);
        let mut cdf_z = vec![0.0f64; nx * ny * (nz + 1)];
        let mut cdf_y = vec![0.0f64; nx * (ny + 1)];
        let mut cdf_x = vec![0.0f64; nx + 1];
        for x in 0..nx {
            for y in 0..ny {
                let base = (x * ny + y) * (nz + 1);
                for z in 0..nz {
                    cdf_z[base + z + 1] = cdf_z[base + z] + w(x, y, z);
                }
                let by = x * (ny + 1);
                cdf_y[by + y + 1] = cdf_y[by + y] + cdf_z[base + nz];
            }
            cdf_x[x + 1] = cdf_x[x] + cdf_y[x * (ny + 1) + ny];
        }
        Distribution3D {
            n,
            total: cdf_x[nx],
            weights,
            cdf_x,
            cdf_y,
            cdf_z,
        }
    }

    /// The probability of voxel `v`.
    pub fn pmf(&self, v: [usize; 3]) -> f32 {
        if self.total <= 0.0 {
            return 0.0;
        }
        let [nx, ny, _] = self.n;
        (f64::from(self.weights[(v[2] * ny + v[1]) * nx + v[0]]) / self.total) as f32
    }

    /// Samples a voxel from three uniform numbers; returns it with its probability.
    pub fn sample(&self, u: [f32; 3]) -> ([usize; 3], f32) {
        let [nx, ny, nz] = self.n;
        let x = pick(&self.cdf_x, u[0]);
        let y = pick(&self.cdf_y[x * (ny + 1)..(x + 1) * (ny + 1)], u[1]);
        let base = (x * ny + y) * (nz + 1);
        let z = pick(&self.cdf_z[base..base + nz + 1], u[2]);
        debug_assert!(x < nx && y < ny && z < nz);
        let v = [x, y, z];
        (v, self.pmf(v))
    }
}

/// The bin of a cumulative table (starting at 0) that `u` in [0, 1) falls in, skipping
/// empty bins.
fn pick(cdf: &[f64], u: f32) -> usize {
    let n = cdf.len() - 1;
    let target = f64::from(u) * cdf[n];
    // The first bin whose upper end exceeds the target.
    let i = cdf[1..].partition_point(|&c| c <= target);
    if i < n {
        return i;
    }
    // Rounding put the target at the very top: the last non-empty bin.
    (0..n).rev().find(|&i| cdf[i + 1] > cdf[i]).unwrap_or(n - 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::PixelSampler;

    fn check_phase(phase: Phase, g: f32, mean_tolerance: f64) {
        let wo = Vec3A::new(0.3, -0.4, 0.866).normalize();
        let n = 1 << 15;
        let (mut integral, mut mean_cos, mut mean_cos_p) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let s = PixelSampler::new(1, 2, i, 3);
            let wi = crate::sampling::uniform_sphere(Vec2::new(s.value(0), s.value(1)));
            let w = phase.p(wo, wi) as f64 * 4.0 * std::f64::consts::PI / n as f64;
            integral += w;
            mean_cos_p += w * wi.dot(-wo) as f64;
            let (ws, pdf) = phase.sample(wo, Vec2::new(s.value(2), s.value(3)));
            assert!((pdf - phase.p(wo, ws)).abs() < 1e-4 * pdf.max(1.0));
            assert!((ws.length() - 1.0).abs() < 1e-4);
            mean_cos += ws.dot(-wo) as f64 / n as f64;
        }
        assert!(
            (integral - 1.0).abs() < 0.02,
            "{phase:?}: integral {integral}"
        );
        // Sampling follows the density: the same mean cosine (in the direction of travel).
        assert!(
            (mean_cos - mean_cos_p).abs() < 0.01,
            "{phase:?}: sampled mean cosine {mean_cos}, density's {mean_cos_p}"
        );
        assert!(
            (mean_cos - g as f64).abs() < mean_tolerance,
            "{phase:?}: mean cosine {mean_cos}, g {g}"
        );
    }

    #[test]
    fn phase_functions_integrate_to_one_and_sample_their_density() {
        for g in [-0.7f32, 0.0, 0.3, 0.9] {
            // HG's mean cosine is g exactly; Schlick's k(g) = 1.55 g - 0.55 g^3 is a fit
            // that misses it by 0.06 at |g| = 0.7
            check_phase(Phase::HenyeyGreenstein { g }, g, 0.01);
            // (and by 0.07 at g = 0.9, where the fit is poorest).
            check_phase(Phase::new(kiln_scene::PhaseDesc::Schlick { g }), g, 0.075);
        }
    }

    #[test]
    fn homogeneous_segment_emission_is_exact() {
        let m = Medium::Homogeneous {
            sigma_a: Color::splat(2.0),
            sigma_s: Color::ZERO,
            le: Color::splat(3.0),
            phase: Phase::HenyeyGreenstein { g: 0.0 },
        };
        let e = m.segment_emission(0.5);
        assert!((e.x - 3.0 * (1.0 - (-1.0f32).exp())).abs() < 1e-6);
        assert!((m.transmittance(0.5).x - (-1.0f32).exp()).abs() < 1e-6);
    }

    fn grid(n: [usize; 3], f: impl Fn(usize, usize, usize) -> f32) -> kiln_scene::VoxelGrid {
        let mut values = Vec::new();
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    values.push(f(x, y, z));
                }
            }
        }
        kiln_scene::VoxelGrid {
            nx: n[0],
            ny: n[1],
            nz: n[2],
            values,
        }
    }

    #[test]
    fn sampled_grid_interpolates_like_pbrt() {
        let g = SampledGrid::new(&grid([2, 1, 1], |x, _, _| [1.0, 3.0][x]));
        // Sample centres at x = 0.25 and 0.75; zero beyond them, half way at the faces.
        assert_eq!(g.lookup(Vec3A::new(0.25, 0.5, 0.5)), 1.0);
        assert_eq!(g.lookup(Vec3A::new(0.5, 0.5, 0.5)), 2.0);
        assert_eq!(g.lookup(Vec3A::new(0.75, 0.5, 0.5)), 3.0);
        assert!((g.lookup(Vec3A::new(0.0, 0.5, 0.5)) - 0.5).abs() < 1e-6);
        assert!((g.lookup(Vec3A::new(0.5, 0.5, 0.0)) - 1.0).abs() < 1e-6);
        assert_eq!(g.lookup(Vec3A::new(-0.5, 0.5, 0.5)), 0.0);
        assert_eq!(g.max_over(Vec3A::ZERO, Vec3A::new(0.2, 1.0, 1.0)), 1.0);
        assert_eq!(g.max_over(Vec3A::ZERO, Vec3A::new(0.3, 1.0, 1.0)), 3.0);
    }

    fn medium(density: kiln_scene::VoxelGrid, emission: kiln_scene::GridEmission) -> GridMedium {
        GridMedium::new(&kiln_scene::GridMediumDesc {
            sigma_a: [0.5, 0.5, 0.5],
            sigma_s: [1.5, 1.0, 0.5],
            phase: kiln_scene::PhaseDesc::HenyeyGreenstein { g: 0.0 },
            density,
            emission,
            p0: [-1.0, -1.0, -1.0],
            p1: [1.0, 1.0, 3.0],
            medium_to_world: glam::DMat4::from_rotation_y(0.3),
        })
    }

    #[test]
    fn ratio_tracking_matches_the_optical_depth() {
        // Density varies along x; the ray crosses the middle of the box, where the
        // interpolation is exact, so the optical depth is known in closed form.
        let n = 8;
        let m = medium(
            grid([n, 4, 4], |x, _, _| 0.2 + 0.1 * x as f32),
            kiln_scene::GridEmission::None,
        );
        let to_world = glam::Affine3A::from_mat4(glam::Mat4::from_rotation_y(0.3));
        let o = to_world.transform_point3a(Vec3A::new(-0.75, 0.0, 1.0));
        let d = to_world.transform_vector3a(Vec3A::X);
        // Box x from -1 to 1: density(x) at sample centres, linear between 0.2 (x=-0.875)
        // and 0.9 (x=0.875); over [-0.75, 0.75] its mean is the midpoint value 0.55.
        let sigma_t = Color::new(2.0, 1.5, 1.0);
        let exact = (-sigma_t * 0.55 * 1.5).exp();
        let runs = 20_000;
        let mut sum = Color::ZERO;
        for i in 0..runs {
            let mut rng = TrackingRng::new(i);
            sum += m.transmittance(o, d, 1.5, &mut rng);
        }
        let mean = sum / runs as f32;
        for c in 0..3 {
            assert!(
                (mean[c] - exact[c]).abs() < 0.015,
                "channel {c}: {} vs {}",
                mean[c],
                exact[c]
            );
        }
        // Tentative collisions come at the majorant's rate, and only inside the box.
        let mut count = 0u64;
        let mut rng = TrackingRng::new(7);
        for _ in 0..2000 {
            m.walk(o - d * 5.0, d, 100.0, &mut rng, |t, p, sigma_maj| {
                assert!(t > 5.0 - 0.25 - 1e-3 && t < 5.0 + 1.75 + 1e-3, "t {t}");
                assert!(p.min_element() >= -1e-4 && p.max_element() <= 1.0 + 1e-4);
                assert!(sigma_maj >= 2.0 * m.density(p) - 1e-5);
                count += 1;
                true
            });
        }
        assert!(count > 2000, "{count}");
    }

    #[test]
    fn emission_distribution_matches_its_weights_and_pdf() {
        let n = [6, 5, 4];
        let temperature = grid(n, |x, y, z| {
            800.0 + 300.0 * x as f32 + 100.0 * (y * z) as f32
        });
        let m = medium(
            grid(n, |x, y, z| ((x + 2 * y + z) % 4) as f32 * 0.5),
            kiln_scene::GridEmission::Temperature {
                temperature,
                offset: 0.0,
                t_scale: 1.0,
                scale: grid([1, 1, 1], |_, _, _| 1.0),
            },
        );
        let dist = m.emission_distribution.as_ref().unwrap();
        // Chi-square of a histogram of sampled voxels against the distribution's pmf.
        let voxels = n[0] * n[1] * n[2];
        let samples = 200_000;
        let mut hist = vec![0u32; voxels];
        let mut rng = TrackingRng::new(3);
        for i in 0..samples {
            let s = PixelSampler::new(5, 0, i, 11);
            let u = [s.value(0), s.value(1), s.value(2)];
            let (v, pmf) = dist.sample(u);
            assert_eq!(pmf, dist.pmf(v));
            hist[(v[2] * n[1] + v[1]) * n[0] + v[0]] += 1;
            // The world point's density equals what emission_pdf returns for it.
            let (p, pdf) = m.sample_emission(u, &mut rng).unwrap();
            let back = m.emission_pdf(p);
            assert!((pdf - back).abs() <= 1e-4 * pdf, "pdf {pdf} vs {back}");
        }
        let (mut chi2, mut dof) = (0.0f64, 0usize);
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let expected = dist.pmf([x, y, z]) as f64 * samples as f64;
                    let got = hist[(z * n[1] + y) * n[0] + x] as f64;
                    if expected == 0.0 {
                        assert_eq!(got, 0.0, "voxel ({x},{y},{z}) has no weight");
                        continue;
                    }
                    chi2 += (got - expected).powi(2) / expected;
                    dof += 1;
                }
            }
        }
        // The 99.9% point of chi-square with ~120 degrees of freedom is about 170.
        let limit = dof as f64 + 4.5 * (2.0 * dof as f64).sqrt();
        assert!(
            dof > 60 && chi2 < limit,
            "chi2 {chi2} with {dof} bins (limit {limit})"
        );
        // The pdf integrates to one over the box.
        let box_volume = m.box_volume as f64;
        let mut integral = 0.0f64;
        let k = 40_000;
        for i in 0..k {
            let s = PixelSampler::new(9, 0, i, 2);
            let b = Vec3A::new(s.value(0), s.value(1), s.value(2));
            integral +=
                m.emission_pdf(m.box_to_world.transform_point3a(b)) as f64 * box_volume / k as f64;
        }
        assert!((integral - 1.0).abs() < 0.02, "{integral}");
    }
}
