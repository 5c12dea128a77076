//! A heterogeneous medium: pbrt-v4's "uniformgrid" (density, emission and temperature
//! grids), "rgbgrid" (RGB coefficient and emission grids), "cloud" (a procedural density)
//! and "nanovdb" (density and temperature grids from a NanoVDB file, on its lattice), tracked against a coarse majorant grid walked with a 3D DDA, and its
//! emission distribution for sampling it as a light (seed 001).

mod spectra;

use super::cloud::Cloud;
use super::{MediumEvent, Phase, SampledGrid};
use crate::math::{Color, Ray};
use crate::sampling::{Distribution3D, TrackingRng};
use crate::spectral::Wavelengths;
use crate::work::MAX_TRACKING_STEPS;
use glam::{Affine3A, Vec3A};

/// Where a grid medium's emitted radiance comes from.
#[derive(Debug, Clone)]
enum Emission {
    Constant(Color),
    /// An RGB grid (the channels), times a scale.
    Rgb(Box<[SampledGrid; 3]>, f32),
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
    /// What every entry is multiplied by.
    scale: f32,
    t_max: f32,
    step: f32,
    rgb: Vec<Color>,
}

const BLACKBODY_MIN_K: f32 = 100.0;

impl BlackbodyTable {
    /// The table up to `t_max`, every entry times `scale`.
    fn new(t_max: f32, scale: f32) -> BlackbodyTable {
        let n = 2048usize;
        let t_max = t_max.max(BLACKBODY_MIN_K * 2.0);
        let step = (t_max - BLACKBODY_MIN_K) / (n - 1) as f32;
        let rgb = (0..n)
            .map(|i| {
                crate::math::rgb(kiln_scene::spectrum::blackbody_peak_rgb(
                    BLACKBODY_MIN_K + step * i as f32,
                )) * scale
            })
            .collect();
        BlackbodyTable {
            scale,
            t_max,
            step,
            rgb,
        }
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

/// How a walk through the majorant grid ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Walk {
    /// It reached the segment's end or left the box.
    Ended,
    /// The visitor stopped it.
    Stopped,
    /// It visited [`MAX_TRACKING_STEPS`] collisions and was cut off there.
    CutOff,
}

/// What multiplies `sigma_a` and `sigma_s` at a point of the unit box.
#[derive(Debug, Clone)]
enum Field {
    /// One density for both ("uniformgrid").
    Scalar(SampledGrid),
    /// RGB grids per coefficient, 1 where absent ("rgbgrid").
    Rgb {
        a: Option<Box<[SampledGrid; 3]>>,
        s: Option<Box<[SampledGrid; 3]>>,
    },
    /// The procedural cloud, evaluated in the medium's space `p0 + p (p1 - p0)`.
    Cloud {
        cloud: Cloud,
        p0: Vec3A,
        size: Vec3A,
    },
}

fn rgb_lookup(g: &Option<Box<[SampledGrid; 3]>>, p: Vec3A) -> Color {
    g.as_deref().map_or(Color::ONE, |[r, gr, b]| {
        crate::math::rgb3(r.lookup(p), gr.lookup(p), b.lookup(p))
    })
}

fn rgb_max_over(g: &Option<Box<[SampledGrid; 3]>>, lo: Vec3A, hi: Vec3A) -> Color {
    g.as_deref().map_or(Color::ONE, |[r, gr, b]| {
        crate::math::rgb3(r.max_over(lo, hi), gr.max_over(lo, hi), b.max_over(lo, hi))
    })
}

/// Cells of the majorant grid along each axis: 16 for grids on the centred lattice and the
/// cloud, 64 for NanoVDB grids (pbrt-v4's choices; NanoVDB grids are usually larger).
const MAJORANT_RES: usize = 16;
const MAJORANT_RES_NANOVDB: usize = 64;

/// A heterogeneous medium: pbrt-v4's "uniformgrid". Tracking runs against a coarse grid of
/// majorants (the largest density each cell can hold), walked cell by cell with a 3D DDA.
#[derive(Debug, Clone)]
pub struct GridMedium {
    /// Per unit density.
    pub sigma_a: Color,
    pub sigma_s: Color,
    pub phase: Phase,
    field: Field,
    /// The emission and the grid that scales it (None: 1).
    emission: Option<(Emission, Option<SampledGrid>)>,
    /// World space to the unit box.
    world_to_box: Affine3A,
    box_to_world: Affine3A,
    /// Majorant cells along each axis.
    res: usize,
    /// Per cell, the largest sigma_t channel anywhere in it.
    majorant: Vec<f32>,
    /// World-space volume of the box.
    box_volume: f32,
    /// The distribution of emitted luminance over voxels, for sampling it as a light.
    pub emission_distribution: Option<Distribution3D>,
    /// Its RGB inputs as spectra, for a spectral render (None: built for RGB).
    spectra: Option<Box<spectra::GridSpectra>>,
}

impl GridMedium {
    /// The grid's box in world space (the bounds of its transformed corners).
    pub fn world_bounds(&self) -> (Vec3A, Vec3A) {
        crate::shapes::transformed_bounds(&self.box_to_world, Vec3A::ZERO, Vec3A::ONE)
    }

    /// The medium a description gives, for a spectral render if `spectral` (its majorants
    /// then bound every wavelength's extinction).
    pub fn new(desc: &kiln_scene::GridMediumDesc, spectral: bool) -> GridMedium {
        let p0 = Vec3A::from(desc.p0);
        let p1 = Vec3A::from(desc.p1);
        let medium_to_world = Affine3A::from_mat4(desc.medium_to_world.as_mat4());
        let box_to_medium =
            Affine3A::from_translation((p0).into()) * Affine3A::from_scale((p1 - p0).into());
        let box_to_world = medium_to_world * box_to_medium;
        let world_to_box = box_to_world.inverse();
        let lattice = &desc.lattice;
        let grid = |g: &kiln_scene::VoxelGrid| SampledGrid::on(g, lattice);
        let field = match &desc.density {
            kiln_scene::GridDensity::Scalar(g) => Field::Scalar(grid(g)),
            kiln_scene::GridDensity::Rgb { sigma_a, sigma_s } => {
                let grids = |g: &Option<Box<[kiln_scene::VoxelGrid; 3]>>| {
                    g.as_deref().map(|g| Box::new(g.each_ref().map(grid)))
                };
                Field::Rgb {
                    a: grids(sigma_a),
                    s: grids(sigma_s),
                }
            }
            kiln_scene::GridDensity::Cloud {
                density,
                wispiness,
                frequency,
            } => Field::Cloud {
                cloud: Cloud {
                    density: *density,
                    wispiness: *wispiness,
                    frequency: *frequency,
                },
                p0,
                size: p1 - p0,
            },
        };
        let emission = match &desc.emission {
            kiln_scene::GridEmission::None => None,
            kiln_scene::GridEmission::Constant { le, scale, .. } => {
                Some((Emission::Constant(crate::math::rgb(*le)), Some(grid(scale))))
            }
            kiln_scene::GridEmission::Temperature {
                temperature,
                offset,
                t_scale,
                scale,
                le_scale,
            } => {
                let temperature = grid(temperature);
                let t_max = (temperature.max() - offset) * t_scale;
                Some((
                    Emission::Temperature {
                        grid: temperature,
                        offset: *offset,
                        t_scale: *t_scale,
                        table: BlackbodyTable::new(t_max.max(0.0), *le_scale),
                    },
                    scale.as_ref().map(grid),
                ))
            }
            kiln_scene::GridEmission::Rgb { le, scale } => Some((
                Emission::Rgb(Box::new(le.each_ref().map(grid)), *scale),
                None,
            )),
        };
        let sigma_a = crate::math::rgb(desc.sigma_a);
        let sigma_s = crate::math::rgb(desc.sigma_s);
        let r = match desc.lattice {
            kiln_scene::Lattice::Centred => MAJORANT_RES,
            kiln_scene::Lattice::Affine { .. } => MAJORANT_RES_NANOVDB,
        };
        let mut m = GridMedium {
            sigma_a,
            sigma_s,
            phase: Phase::new(desc.phase),
            field,
            emission,
            world_to_box,
            box_to_world,
            res: r,
            majorant: Vec::new(),
            box_volume: box_to_world.matrix3.determinant().abs(),
            emission_distribution: None,
            spectra: None,
        };
        if spectral {
            m.spectra = Some(Box::new(spectra::GridSpectra::new(&m, desc)));
        }
        m.majorant = m.majorants();
        m.emission_distribution = m.build_distribution();
        m
    }

    /// Per cell of the majorant grid, the largest sigma_t anywhere in it: of any channel,
    /// and for a spectral render of any wavelength.
    fn majorants(&self) -> Vec<f32> {
        let r = self.res;
        let (sigma_a, sigma_s) = (self.sigma_a, self.sigma_s);
        let mut majorant = vec![0.0; r * r * r];
        for z in 0..r {
            for y in 0..r {
                for x in 0..r {
                    let lo = Vec3A::new(x as f32, y as f32, z as f32) / r as f32;
                    let hi = lo + Vec3A::splat(1.0 / r as f32);
                    let max_t = match &self.field {
                        Field::Scalar(g) => (sigma_a + sigma_s) * g.max_over(lo, hi),
                        Field::Rgb { a, s } => {
                            sigma_a * rgb_max_over(a, lo, hi) + sigma_s * rgb_max_over(s, lo, hi)
                        }
                        // The cloud's density is at most 1.
                        Field::Cloud { .. } => sigma_a + sigma_s,
                    };
                    let spectral = self
                        .spectra
                        .as_ref()
                        .map_or(0.0, |sp| sp.majorant(&self.field, lo, hi));
                    majorant[(z * r + y) * r + x] = max_t.max_element().max(spectral);
                }
            }
        }
        majorant
    }

    /// sigma_a and sigma_s at `p` in the unit box.
    pub fn coefficients(&self, p: Vec3A) -> (Color, Color) {
        match &self.field {
            Field::Scalar(g) => {
                let d = g.lookup(p);
                (self.sigma_a * d, self.sigma_s * d)
            }
            Field::Rgb { a, s } => (
                self.sigma_a * rgb_lookup(a, p),
                self.sigma_s * rgb_lookup(s, p),
            ),
            Field::Cloud { cloud, p0, size } => {
                let d = cloud.density_at(*p0 + p * *size);
                (self.sigma_a * d, self.sigma_s * d)
            }
        }
    }

    /// The resolution the emission is given at (its distribution's voxels).
    fn resolution(&self) -> [usize; 3] {
        match (&self.field, &self.emission) {
            (_, Some((Emission::Rgb(g, _), _))) => g[0].n,
            (Field::Scalar(g), _) => g.n,
            (Field::Rgb { a: Some(g), .. }, _) | (Field::Rgb { s: Some(g), .. }, _) => g[0].n,
            _ => [16, 16, 16],
        }
    }

    pub fn is_emissive(&self) -> bool {
        self.emission.is_some() && self.sigma_a.max_element() > 0.0
    }

    /// Emitted radiance Le at `p` in the unit box (the source term is sigma_a * density * Le).
    pub fn le(&self, p: Vec3A) -> Color {
        let Some((emission, scale)) = &self.emission else {
            return Color::ZERO;
        };
        let s = scale.as_ref().map_or(1.0, |g| g.lookup(p));
        if s <= 0.0 {
            return Color::ZERO;
        }
        match emission {
            Emission::Constant(le) => *le * s,
            Emission::Rgb(grids, scale) => {
                let [r, g, b] = &**grids;
                crate::math::rgb3(r.lookup(p), g.lookup(p), b.lookup(p)) * (*scale * s)
            }
            Emission::Temperature {
                grid,
                offset,
                t_scale,
                table,
            } => table.at((grid.lookup(p) - offset) * t_scale) * s,
        }
    }

    pub fn to_box(&self, world: Vec3A) -> Vec3A {
        self.world_to_box.transform_point3a(world)
    }

    /// The majorant (tentative collisions per unit length) at `p` in the unit box.
    pub fn majorant_at(&self, p: Vec3A) -> f32 {
        if p.min_element() < 0.0 || p.max_element() > 1.0 {
            return 0.0;
        }
        let r = self.res;
        let c = (p * r as f32)
            .as_uvec3()
            .min(glam::UVec3::splat(r as u32 - 1));
        self.majorant[(c.z as usize * r + c.y as usize) * r + c.x as usize]
    }

    /// Visits the tentative collisions along the ray from `o` in unit direction `d` over
    /// (0, t_max): a Poisson process whose rate is the majorant of the cell the point is in.
    /// `visit(t, p_box, sigma_maj)` returns false to stop. A walk visits at most
    /// [`MAX_TRACKING_STEPS`] collisions.
    pub fn walk(
        &self,
        o: Vec3A,
        d: Vec3A,
        t_max: f32,
        rng: &mut TrackingRng,
        mut visit: impl FnMut(f32, Vec3A, f32) -> bool,
    ) -> Walk {
        let mut steps = 0u32;
        let r = self.res as f32;
        let oc = self.world_to_box.transform_point3a(o) * r;
        let dc = self.world_to_box.transform_vector3a(d) * r;
        // Clip to the box [0, r]^3.
        let (mut t, mut t_end) = (0.0f32, t_max);
        for a in 0..3 {
            if dc[a] == 0.0 {
                if oc[a] < 0.0 || oc[a] > r {
                    return Walk::Ended;
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
            return Walk::Ended;
        }
        let p = oc + dc * t;
        let n = self.res as i32;
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
        let mut tau = -libm::logf(1.0 - rng.next_f32());
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
            let sigma_maj = self.majorant[idx];
            if sigma_maj > 0.0 {
                loop {
                    let dt = tau / sigma_maj;
                    if t + dt >= t_exit {
                        tau -= sigma_maj * (t_exit - t);
                        break;
                    }
                    t += dt;
                    tau = -libm::logf(1.0 - rng.next_f32());
                    steps += 1;
                    if steps > MAX_TRACKING_STEPS {
                        return Walk::CutOff;
                    }
                    if !visit(t, (oc + dc * t) / r, sigma_maj) {
                        return Walk::Stopped;
                    }
                }
            }
            t = t_exit;
            if t >= t_end {
                return Walk::Ended;
            }
            cell[axis] += step[axis];
            if cell[axis] < 0 || cell[axis] >= n {
                return Walk::Ended;
            }
            next[axis] += delta[axis];
        }
    }

    /// Transmittance along the ray over (0, t_max) by ratio tracking, with Russian roulette
    /// once it is small; None if the walk was cut off. With `waves`, at a spectral path's
    /// wavelengths.
    pub fn transmittance(
        &self,
        o: Vec3A,
        d: Vec3A,
        t_max: f32,
        rng: &mut TrackingRng,
        waves: Option<&Wavelengths>,
    ) -> Option<Color> {
        let mut tr = Color::ONE;
        let mut u = rng.split(0x5851_f42d_4c95_7f2d);
        let lanes = self.lanes(waves);
        let walk = self.walk(o, d, t_max, rng, |_, p, sigma_maj| {
            let (a, s) = self.coefficients_in(p, &lanes);
            let st = a + s;
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
        (walk != Walk::CutOff).then_some(tr)
    }

    /// Tracking against the majorants: at each tentative collision the emission is handed
    /// to `emission` (see [`Medium::sample_interaction`]), then absorption, scattering or a
    /// null collision is chosen with probabilities from the coefficients averaged over the
    /// channels (a spectral path's wavelengths, with `waves`). The weights
    /// sigma_x / (sigma_maj P_x) keep the estimate unbiased for coloured media (and are
    /// exactly 1 for grey ones: plain delta tracking).
    pub(super) fn track(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut TrackingRng,
        beta: &mut Color,
        waves: Option<&Wavelengths>,
        mut emission: impl FnMut(f32, f32, Color),
    ) -> MediumEvent {
        let mut event = MediumEvent::Crossed;
        let mut choice = TrackingRng::new(rng.next_f32().to_bits() as u64 ^ 0x6a09_e667_f3bc_c909);
        let emissive = self.is_emissive();
        let coefficients = self.lanes(waves);
        let lanes = if waves.is_some() { 4 } else { 3 };
        let walk = self.walk(ray.origin, ray.dir, t_max, rng, |t, p, sigma_maj| {
            let (sigma_a, sigma_s) = self.coefficients_in(p, &coefficients);
            if sigma_a == Color::ZERO && sigma_s == Color::ZERO {
                return true;
            }
            if emissive {
                let le = self.le_at(p, waves);
                if le != Color::ZERO {
                    emission(t, sigma_maj, *beta * sigma_a * le);
                }
            }
            let p_a = super::lane_sum(sigma_a, lanes) / (lanes as f32 * sigma_maj);
            let p_s = super::lane_sum(sigma_s, lanes) / (lanes as f32 * sigma_maj);
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
        if walk == Walk::CutOff {
            return MediumEvent::CutOff;
        }
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
        let [nx, ny, nz] = self.resolution();
        let size = Vec3A::new(nx as f32, ny as f32, nz as f32);
        let lum = |p: Vec3A| crate::math::luminance(self.source_at(p, None)).max(0.0);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::media::voxel_grid::grid_from_fn as grid;
    use crate::sampling::PixelSampler;

    fn medium(density: kiln_scene::VoxelGrid, emission: kiln_scene::GridEmission) -> GridMedium {
        GridMedium::new(
            &kiln_scene::GridMediumDesc {
                sigma_a: [0.5, 0.5, 0.5],
                sigma_s: [1.5, 1.0, 0.5],
                phase: kiln_scene::PhaseDesc::HenyeyGreenstein { g: 0.0 },
                density: kiln_scene::GridDensity::Scalar(density),
                emission,
                p0: [-1.0, -1.0, -1.0],
                p1: [1.0, 1.0, 3.0],
                medium_to_world: glam::DMat4::from_rotation_y(0.3),
                lattice: kiln_scene::Lattice::Centred,
            },
            false,
        )
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
        let sigma_t = crate::math::rgb3(2.0, 1.5, 1.0);
        let exact = (-sigma_t * 0.55 * 1.5).exp();
        let runs = 20_000;
        let mut sum = Color::ZERO;
        for i in 0..runs {
            let mut rng = TrackingRng::new(i);
            sum += m.transmittance(o, d, 1.5, &mut rng, None).unwrap();
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
                let (a, s) = m.coefficients(p);
                assert!(sigma_maj >= (a + s).max_element() - 1e-5);
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
                scale: Some(grid([1, 1, 1], |_, _, _| 1.0)),
                le_scale: 1.0,
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
