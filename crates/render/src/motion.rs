//! Moving transforms: pbrt-v4's animated transform between a start and an end matrix.
//! Each matrix is split into a translation, a rotation and a scale (by polar
//! decomposition, M = T R S); in between, the translations and scales are interpolated
//! linearly and the rotations by spherical interpolation, so a spinning object keeps its
//! shape instead of shrinking through the chord. Before the start time the start matrix
//! holds, after the end time the end matrix.

use glam::{Affine3A, DMat3, DMat4, DQuat, DVec3, Mat3A, Vec3A};

#[derive(Debug, Clone)]
pub struct AnimatedTransform {
    start: Parts,
    end: Parts,
    times: [f32; 2],
}

/// M = T R S.
#[derive(Debug, Clone, Copy)]
struct Parts {
    translation: DVec3,
    rotation: DQuat,
    scale: DMat3,
}

impl Parts {
    fn of(m: &DMat4) -> Parts {
        let translation = m.w_axis.truncate();
        let linear = DMat3::from_mat4(*m);
        // Polar decomposition: average the matrix with its inverse transpose until it is a
        // rotation (converges quadratically for any invertible matrix).
        let mut r = linear;
        for _ in 0..100 {
            let next = (r + r.inverse().transpose()) * 0.5;
            let diff = (next - r)
                .to_cols_array()
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()));
            r = next;
            if diff < 1e-12 {
                break;
            }
        }
        // A reflection is carried by the scale, so the rotation is proper.
        if r.determinant() < 0.0 {
            r = -r;
        }
        Parts {
            translation,
            rotation: DQuat::from_mat3(&r).normalize(),
            scale: r.inverse() * linear,
        }
    }

    fn matrix(&self) -> DMat4 {
        DMat4::from_translation(self.translation)
            * DMat4::from_quat(self.rotation)
            * DMat4::from_mat3(self.scale)
    }
}

impl AnimatedTransform {
    /// From `start` at `times[0]` to `end` at `times[1]`.
    pub fn new(start: DMat4, end: DMat4, times: [f64; 2]) -> AnimatedTransform {
        let (mut a, b) = (Parts::of(&start), Parts::of(&end));
        // The shorter way round.
        if a.rotation.dot(b.rotation) < 0.0 {
            a.rotation = -a.rotation;
        }
        AnimatedTransform {
            start: a,
            end: b,
            times: [times[0] as f32, times[1] as f32],
        }
    }

    /// The transform at `time`.
    pub fn at(&self, time: f32) -> DMat4 {
        let span = self.times[1] - self.times[0];
        // With equal times the end holds from then on, as in pbrt-v4.
        let f = if span > 0.0 {
            f64::from(((time - self.times[0]) / span).clamp(0.0, 1.0))
        } else if time > self.times[0] {
            1.0
        } else {
            0.0
        };
        self.at_fraction(f)
    }

    /// The transform a fraction `f` of the way from start to end.
    fn at_fraction(&self, f: f64) -> DMat4 {
        let parts = Parts {
            translation: self.start.translation.lerp(self.end.translation, f),
            rotation: self.start.rotation.slerp(self.end.rotation, f),
            scale: self.start.scale * (1.0 - f) + self.end.scale * f,
        };
        parts.matrix()
    }

    /// The transform at `time` and its inverse, in single precision for tracing.
    pub fn affine_at(&self, time: f32) -> (Affine3A, Affine3A) {
        let m = self.at(time);
        (
            Affine3A::from_mat4(m.as_mat4()),
            Affine3A::from_mat4(m.inverse().as_mat4()),
        )
    }

    /// The world bounds of the object-space box (lo, hi) over the whole motion: its
    /// corners at 65 instants, grown by half the largest step a corner takes between two
    /// of them (which covers the bulge of an arc between its chords).
    pub fn motion_bounds(&self, lo: Vec3A, hi: Vec3A) -> (Vec3A, Vec3A) {
        let corners: Vec<Vec3A> = (0..8)
            .map(|i| {
                Vec3A::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let n = 64;
        let mut blo = Vec3A::splat(f32::INFINITY);
        let mut bhi = Vec3A::splat(f32::NEG_INFINITY);
        let mut step = 0.0f32;
        let mut previous: Option<Vec<Vec3A>> = None;
        for k in 0..=n {
            let m = Affine3A::from_mat4(self.at_fraction(f64::from(k) / f64::from(n)).as_mat4());
            let now: Vec<Vec3A> = corners.iter().map(|c| m.transform_point3a(*c)).collect();
            for p in &now {
                blo = blo.min(*p);
                bhi = bhi.max(*p);
            }
            if let Some(prev) = &previous {
                for (a, b) in prev.iter().zip(&now) {
                    step = step.max((*a - *b).length());
                }
            }
            previous = Some(now);
        }
        (blo - step * 0.5, bhi + step * 0.5)
    }
}

/// The normal matrix of an affine map (the inverse transpose of its linear part).
pub fn normal_matrix(m: &Affine3A) -> Mat3A {
    m.matrix3.inverse().transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DMat4, b: DMat4) -> bool {
        a.to_cols_array()
            .iter()
            .zip(b.to_cols_array())
            .all(|(x, y)| (x - y).abs() < 1e-6)
    }

    /// The ends are the given matrices, whatever they hold (rotation, non-uniform scale,
    /// shear, reflection); times outside the interval hold the nearer end.
    #[test]
    fn the_ends_are_the_given_transforms() {
        let a = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0))
            * DMat4::from_rotation_y(0.7)
            * DMat4::from_scale(DVec3::new(2.0, 0.5, 1.0));
        let b = DMat4::from_rotation_z(2.5) * DMat4::from_scale(DVec3::new(-1.0, 1.0, 3.0));
        let m = AnimatedTransform::new(a, b, [0.0, 2.0]);
        assert!(close(m.at(0.0), a) && close(m.at(-1.0), a));
        assert!(close(m.at(2.0), b) && close(m.at(5.0), b));
    }

    /// With equal transform times the end holds from then on (pbrt-v4), and the bounds
    /// cover both ends.
    #[test]
    fn equal_times_jump_to_the_end() {
        let end = DMat4::from_translation(DVec3::new(5.0, 0.0, 0.0));
        let m = AnimatedTransform::new(DMat4::IDENTITY, end, [0.0, 0.0]);
        assert!(close(m.at(0.0), DMat4::IDENTITY) && close(m.at(0.5), end));
        let (lo, hi) = m.motion_bounds(Vec3A::splat(-1.0), Vec3A::splat(1.0));
        assert!(lo.x <= -1.0 && hi.x >= 6.0, "{lo} {hi}");
    }

    /// A quarter turn halfway is an eighth of a turn, not the chord's shrunken matrix; a
    /// translation halfway is half of it.
    #[test]
    fn rotations_turn_and_translations_slide() {
        let m = AnimatedTransform::new(
            DMat4::IDENTITY,
            DMat4::from_translation(DVec3::new(4.0, 0.0, 0.0))
                * DMat4::from_rotation_z(std::f64::consts::FRAC_PI_2),
            [0.0, 1.0],
        );
        let half = m.at(0.5);
        assert!(close(
            half,
            DMat4::from_translation(DVec3::new(2.0, 0.0, 0.0))
                * DMat4::from_rotation_z(std::f64::consts::FRAC_PI_4)
        ));
        // The bounds cover every instant.
        let (lo, hi) = m.motion_bounds(Vec3A::splat(-1.0), Vec3A::splat(1.0));
        for k in 0..=100 {
            let p = Affine3A::from_mat4(m.at(k as f32 / 100.0).as_mat4())
                .transform_point3a(Vec3A::new(1.0, 1.0, 1.0));
            assert!(
                p.cmpge(lo - 1e-4).all() && p.cmple(hi + 1e-4).all(),
                "{p} outside {lo} {hi}"
            );
        }
    }
}
