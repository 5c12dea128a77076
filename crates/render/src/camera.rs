//! Cameras: pbrt's perspective and orthographic projections, with a thin lens for depth of
//! field, and its spherical camera (every direction, equal-area or equirectangular). A camera turns a film position and a lens sample into a ray, and estimates a
//! pixel's footprint on a surface (for texture filtering).

use crate::lens::LensSystem;
use crate::math::{Frame, Ray};
use crate::motion::AnimatedTransform;
use crate::sampling::concentric_disk;
use glam::{Affine3A, Mat3A, Vec2, Vec3A};
use kiln_scene::{CameraDesc, Projection};

#[derive(Debug, Clone)]
pub struct Camera {
    camera_to_world: Affine3A,
    orthographic: bool,
    /// pbrt-v4's spherical camera: Some(equal area) (it has no lens and no screen window).
    spherical: Option<bool>,
    /// tan(fov / 2) for perspective, 1 for orthographic.
    scale: f32,
    screen: [f32; 4],
    resolution: Vec2,
    lens_radius: f32,
    focal_distance: f32,
    footprint: Footprint,
    /// A moving camera's transform over the shutter (the footprint uses the start).
    motion: Option<AnimatedTransform>,
    /// pbrt-v4's realistic camera: rays traced through its lens system, each with a weight.
    lens: Option<std::sync::Arc<LensSystem>>,
}

/// pbrt-v4's camera-ray footprint approximation: the smallest change of a camera ray's
/// origin and direction from one pixel to the next, over the film, in camera space. A
/// surface point's footprint is where rays so offset from one aimed straight at it meet its
/// tangent plane.
#[derive(Debug, Clone, Default)]
struct Footprint {
    camera_from_world: Affine3A,
    min_pos_dx: Vec3A,
    min_pos_dy: Vec3A,
    min_dir_dx: Vec3A,
    min_dir_dy: Vec3A,
}

impl Camera {
    /// A camera whose transform interpolates between `desc`'s start and end transforms at
    /// `times` (pbrt-v4's TransformTimes), if it moves.
    /// A camera for a film of `xres` x `yres` pixels and `diagonal` metres (the realistic
    /// camera's film size); an error where a realistic camera's lens cannot focus.
    pub fn new_moving(
        desc: &CameraDesc,
        xres: u32,
        yres: u32,
        diagonal: f64,
        times: [f64; 2],
    ) -> Result<Camera, String> {
        let mut camera = Camera::new(desc, xres, yres);
        camera.motion = desc
            .camera_to_world_end
            .map(|end| AnimatedTransform::new(desc.camera_to_world, end, times));
        if let Projection::Realistic(lens) = &desc.projection {
            camera.lens = Some(std::sync::Arc::new(
                LensSystem::new(lens, xres, yres, diagonal)
                    .map_err(|e| format!("Camera 'realistic': {e}"))?,
            ));
            camera.footprint = camera.minimum_differentials();
        }
        Ok(camera)
    }

    pub fn new(desc: &CameraDesc, xres: u32, yres: u32) -> Camera {
        let aspect = xres as f64 / yres as f64;
        let screen = desc.screen_window.unwrap_or(if aspect > 1.0 {
            [-aspect, aspect, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / aspect, 1.0 / aspect]
        });
        let (orthographic, scale) = match desc.projection {
            Projection::Perspective { fov_degrees } => {
                (false, libm::tan(fov_degrees.to_radians() / 2.0) as f32)
            }
            Projection::Orthographic => (true, 1.0),
            Projection::Spherical { .. } | Projection::Realistic(_) => (false, 1.0),
        };
        let spherical = match desc.projection {
            Projection::Spherical { equal_area } => Some(equal_area),
            _ => None,
        };
        let camera_to_world = Affine3A::from_mat4(desc.camera_to_world.as_mat4());
        let mut camera = Camera {
            camera_to_world,
            orthographic,
            spherical,
            scale,
            screen: screen.map(|v| v as f32),
            resolution: Vec2::new(xres as f32, yres as f32),
            lens_radius: desc.lens_radius as f32,
            focal_distance: desc.focal_distance as f32,
            footprint: Footprint::default(),
            motion: None,
            lens: None,
        };
        camera.footprint = camera.minimum_differentials();
        camera
    }

    /// The world-space ray through continuous raster position `film` (pixels, y down), lens sample `lens`.
    pub fn generate_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        self.generate_ray_at(film, lens, 0.0)
    }

    /// The ray through `film` with lens sample `lens` at `time`, and the weight its
    /// radiance takes (1 but for the realistic camera, whose lens may also stop it: None).
    pub fn generate_weighted_ray_at(
        &self,
        film: Vec2,
        lens: Vec2,
        time: f32,
    ) -> Option<(Ray, f32)> {
        match &self.lens {
            None => Some((self.generate_ray_at(film, lens, time), 1.0)),
            Some(system) => {
                let (origin, dir, weight) = system.generate(film, self.resolution, lens)?;
                Some((self.to_world_ray(origin, dir, time), weight))
            }
        }
    }

    /// Camera space to world space at `time` (a moving camera's transform then).
    pub fn camera_to_world_at(&self, time: f32) -> Affine3A {
        match &self.motion {
            Some(m) => m.affine_at(time).0,
            None => self.camera_to_world,
        }
    }

    fn to_world_ray(&self, origin: Vec3A, dir: Vec3A, time: f32) -> Ray {
        let to_world = self.camera_to_world_at(time);
        Ray::at_time(
            to_world.transform_point3a(origin),
            to_world.transform_vector3a(dir).normalize(),
            time,
        )
    }

    /// As [`Camera::generate_ray`], at `time` in the shutter (where a moving camera is then).
    pub fn generate_ray_at(&self, film: Vec2, lens: Vec2, time: f32) -> Ray {
        let (origin, dir) = self.camera_space_ray(film, lens);
        self.to_world_ray(origin, dir, time)
    }

    /// pbrt-v4's FindMinimumDifferentials: rays through 512 points along the film's
    /// diagonal and their neighbours one pixel right and down, through the lens centre.
    fn minimum_differentials(&self) -> Footprint {
        let mut f = Footprint {
            camera_from_world: self.camera_to_world.inverse(),
            min_pos_dx: Vec3A::INFINITY,
            min_pos_dy: Vec3A::INFINITY,
            min_dir_dx: Vec3A::INFINITY,
            min_dir_dy: Vec3A::INFINITY,
        };
        let centre = Vec2::splat(0.5);
        let n = 512;
        for i in 0..n {
            let film = self.resolution * (i as f32 / (n - 1) as f32);
            let (o, d) = self.camera_space_ray(film, centre);
            let (ox, dx) = self.camera_space_ray(film + Vec2::X, centre);
            let (oy, dy) = self.camera_space_ray(film + Vec2::Y, centre);
            let shorter = |a: Vec3A, b: Vec3A| if a.length() < b.length() { a } else { b };
            f.min_pos_dx = shorter(ox - o, f.min_pos_dx);
            f.min_pos_dy = shorter(oy - o, f.min_pos_dy);
            let frame = Frame::from_z(d);
            let local = |v: Vec3A| frame.to_local(v).normalize() - Vec3A::Z;
            f.min_dir_dx = shorter(local(dx), f.min_dir_dx);
            f.min_dir_dy = shorter(local(dy), f.min_dir_dy);
        }
        f
    }

    /// pbrt-v4's Approximate_dp_dxy: how far the point `p` (normal `n`) moves on its tangent
    /// plane from one pixel to the next, scaled by `scale` (pbrt-v4 uses
    /// max(1/8, 1/sqrt(spp)): with many samples, each filters over less than a pixel).
    pub fn approximate_dp_dxy(&self, p: Vec3A, n: Vec3A, scale: f32) -> (Vec3A, Vec3A) {
        let f = &self.footprint;
        let pc = f.camera_from_world.transform_point3a(p);
        let r = rotate_from_to(pc.normalize_or_zero(), Vec3A::Z);
        let pz = r * pc;
        let nz = r * f.camera_from_world.transform_vector3a(n);
        let d = nz.z * pz.z;
        let hit = |o: Vec3A, dir: Vec3A| {
            let t = -(nz.dot(o) - d) / nz.dot(dir);
            o + t * dir
        };
        let px = hit(f.min_pos_dx, Vec3A::Z + f.min_dir_dx);
        let py = hit(f.min_pos_dy, Vec3A::Z + f.min_dir_dy);
        let back = |v: Vec3A| {
            let w = scale * self.camera_to_world.transform_vector3a(r.transpose() * v);
            if w.is_finite() { w } else { Vec3A::ZERO }
        };
        (back(px - pz), back(py - pz))
    }

    /// The camera-space ray through raster position `film`, lens sample `lens` (for the
    /// realistic camera, where the lens stops it: the ray straight out of the film point).
    fn camera_space_ray(&self, film: Vec2, lens: Vec2) -> (Vec3A, Vec3A) {
        if let Some(system) = &self.lens {
            return match system.generate(film, self.resolution, lens) {
                Some((o, d, _)) => (o, d),
                None => (Vec3A::ZERO, Vec3A::Z),
            };
        }
        if let Some(equal_area) = self.spherical {
            return (
                Vec3A::ZERO,
                spherical_direction(film / self.resolution, equal_area),
            );
        }
        let [x0, x1, y0, y1] = self.screen;
        let sx = x0 + film.x / self.resolution.x * (x1 - x0);
        let sy = y1 - film.y / self.resolution.y * (y1 - y0);
        let (mut origin, mut dir) = if self.orthographic {
            (Vec3A::new(sx, sy, 0.0), Vec3A::Z)
        } else {
            (
                Vec3A::ZERO,
                Vec3A::new(sx * self.scale, sy * self.scale, 1.0).normalize(),
            )
        };
        if self.lens_radius > 0.0 {
            let p_lens = self.lens_radius * concentric_disk(lens);
            let ft = self.focal_distance / dir.z;
            let p_focus = origin + dir * ft;
            origin += Vec3A::new(p_lens.x, p_lens.y, 0.0);
            dir = (p_focus - origin).normalize();
        }
        (origin, dir)
    }
}

/// pbrt-v4's spherical camera's direction (camera space) through film position `uv` in
/// [0, 1]²: on the equal-area square (folded back across its edges, where the octahedral
/// layout continues) or the equirectangular map (θ = π v from the pole, φ = 2π u), both
/// on the z-up sphere and then y and z swapped, as pbrt-v4 builds them.
fn spherical_direction(uv: Vec2, equal_area: bool) -> Vec3A {
    let d = if equal_area {
        let mut p = uv;
        if p.x < 0.0 {
            p = Vec2::new(-p.x, 1.0 - p.y);
        } else if p.x > 1.0 {
            p = Vec2::new(2.0 - p.x, 1.0 - p.y);
        }
        if p.y < 0.0 {
            p = Vec2::new(1.0 - p.x, -p.y);
        } else if p.y > 1.0 {
            p = Vec2::new(1.0 - p.x, 2.0 - p.y);
        }
        crate::sampling::equal_area_square_to_sphere(p)
    } else {
        let theta = std::f32::consts::PI * uv.y;
        let phi = 2.0 * std::f32::consts::PI * uv.x;
        Vec3A::new(
            libm::sinf(theta) * libm::cosf(phi),
            libm::sinf(theta) * libm::sinf(phi),
            libm::cosf(theta),
        )
    };
    Vec3A::new(d.x, d.z, d.y)
}

/// The rotation taking unit vector `from` to unit vector `to`: two reflections (Hughes and
/// Möller), as pbrt-v4's RotateFromTo builds it.
fn rotate_from_to(from: Vec3A, to: Vec3A) -> Mat3A {
    let refl = if from.x.abs() < 0.72 && to.x.abs() < 0.72 {
        Vec3A::X
    } else if from.y.abs() < 0.72 && to.y.abs() < 0.72 {
        Vec3A::Y
    } else {
        Vec3A::Z
    };
    let (u, v) = (refl - from, refl - to);
    let (uu, vv, uv) = (u.dot(u), v.dot(v), u.dot(v));
    let entry = |i: usize, j: usize| {
        let delta = if i == j { 1.0 } else { 0.0 };
        delta - 2.0 / uu * u[i] * u[j] - 2.0 / vv * v[i] * v[j] + 4.0 * uv / (uu * vv) * v[i] * u[j]
    };
    Mat3A::from_cols(
        Vec3A::new(entry(0, 0), entry(1, 0), entry(2, 0)),
        Vec3A::new(entry(0, 1), entry(1, 1), entry(2, 1)),
        Vec3A::new(entry(0, 2), entry(1, 2), entry(2, 2)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;
    use kiln_scene::Loc;

    #[test]
    fn centre_pixel_looks_down_the_view_axis() {
        let desc = CameraDesc {
            projection: Projection::Perspective { fov_degrees: 90.0 },
            camera_to_world: DMat4::from_translation(glam::DVec3::new(1.0, 2.0, 3.0)),
            camera_to_world_end: None,
            lens_radius: 0.0,
            focal_distance: 1e6,
            screen_window: None,
            shutter: [0.0, 1.0],
            loc: Loc::synthetic("t"),
        };
        let cam = Camera::new(&desc, 100, 50);
        let r = cam.generate_ray(Vec2::new(50.0, 25.0), Vec2::splat(0.5));
        assert!((r.dir - Vec3A::Z).length() < 1e-6);
        assert!((r.origin - Vec3A::new(1.0, 2.0, 3.0)).length() < 1e-6);
        // fov applies to the shorter (vertical) axis: the top edge is 45 degrees up.
        let top = cam.generate_ray(Vec2::new(50.0, 0.0), Vec2::splat(0.5));
        assert!((top.dir.y - top.dir.z).abs() < 1e-5 && top.dir.y > 0.0);
        // Raster x grows to the right, which is +x in camera space.
        let right = cam.generate_ray(Vec2::new(100.0, 25.0), Vec2::splat(0.5));
        assert!(right.dir.x > 0.0);
    }

    #[test]
    fn footprint_of_a_facing_plane_is_a_pixel_at_its_distance() {
        // 90° fov over 50 pixels vertically: at distance 10 a pixel at the centre is 0.4
        // units; pbrt-v4 takes the smallest angle over the film (at its corner, about a
        // quarter of that for this wide a view).
        let desc = CameraDesc {
            projection: Projection::Perspective { fov_degrees: 90.0 },
            camera_to_world: DMat4::IDENTITY,
            camera_to_world_end: None,
            lens_radius: 0.0,
            focal_distance: 1e6,
            screen_window: None,
            shutter: [0.0, 1.0],
            loc: Loc::synthetic("t"),
        };
        let cam = Camera::new(&desc, 100, 50);
        let (dx, dy) = cam.approximate_dp_dxy(Vec3A::new(0.0, 0.0, 10.0), -Vec3A::Z, 1.0);
        assert!(dx.z.abs() < 1e-5 && dy.z.abs() < 1e-5, "{dx} {dy}");
        for d in [dx.length(), dy.length()] {
            assert!(d > 0.05 && d <= 0.4 + 1e-4, "{d}");
        }
        // Twice as far, twice as large; scaled by 1/2, half.
        let (dx2, _) = cam.approximate_dp_dxy(Vec3A::new(0.0, 0.0, 20.0), -Vec3A::Z, 0.5);
        assert!((dx2.length() - dx.length()).abs() < 1e-4);
        // A plane seen at a grazing angle stretches the footprint.
        let tilted = Vec3A::new(0.0, 1.0, -0.1).normalize();
        let (dxt, dyt) = cam.approximate_dp_dxy(Vec3A::new(0.0, 0.0, 10.0), tilted, 1.0);
        let (before, after) = (dx.length().max(dy.length()), dxt.length().max(dyt.length()));
        assert!(after > 3.0 * before, "{after} vs {before}");
    }

    #[test]
    fn rotation_takes_from_to_to() {
        for from in [Vec3A::X, Vec3A::new(0.3, -0.5, 0.8).normalize(), -Vec3A::Z] {
            let r = rotate_from_to(from, Vec3A::Z);
            assert!((r * from - Vec3A::Z).length() < 1e-5, "{from}");
            assert!((r.determinant() - 1.0).abs() < 1e-5);
        }
    }
}
