//! The film's pixel sensor, as pbrt-v4's: a camera sample's radiance times the imaging
//! ratio (the shutter's exposure time · ISO / 100), taken into the sensor's space (XYZ for
//! the CIE 1931 observer, a named camera's raw RGB), its largest component there clamped to
//! "maxcomponentvalue", then white balanced into the image's linear sRGB ("whitebalance":
//! from daylight at that temperature to the sRGB white; a camera's fitted matrix,
//! `kiln_scene::camera_sensor`). With pbrt-v4's defaults it is the identity and costs
//! nothing.

use crate::math::{Color, rgb_of, rgb_vec, vec_rgb};
use crate::spectral::Wavelengths;
use glam::{Mat3A, Vec3A, Vec4};
use kiln_scene::SensorDesc;
use kiln_scene::camera_sensor::RawTable;
use kiln_scene::spectrum::{SRGB_TO_XYZ, white_balance_srgb};

#[derive(Debug, Clone)]
pub struct Sensor {
    ratio: f32,
    max_component: f32,
    /// Linear sRGB to XYZ, where the clamp is taken.
    to_xyz: Mat3A,
    balance: Option<Mat3A>,
    /// A named camera: linear sRGB to its raw RGB, and raw RGB to the image.
    camera: Option<(std::sync::Arc<RawTable>, Mat3A)>,
    /// A named camera's responses per nanometre from 360 nm (the fourth lane 0), through
    /// which a spectral sample is recorded.
    curves: Option<std::sync::Arc<[Vec4]>>,
}

fn mat(rows: [[f64; 3]; 3]) -> Mat3A {
    Mat3A::from_cols_array_2d(&rows.map(|r| r.map(|v| v as f32))).transpose()
}

impl Sensor {
    pub fn new(desc: &SensorDesc, exposure_time: f64) -> Sensor {
        Sensor {
            ratio: (exposure_time * desc.iso / 100.0) as f32,
            max_component: desc.max_component as f32,
            to_xyz: mat(SRGB_TO_XYZ),
            balance: (desc.white_balance != 0.0 && desc.camera.is_none())
                .then(|| mat(white_balance_srgb(desc.white_balance))),
            camera: desc
                .camera
                .as_ref()
                .map(|c| (std::sync::Arc::new(c.raw.clone()), mat(c.raw_to_srgb))),
            curves: desc.camera.as_ref().map(|c| {
                c.per_nm
                    .iter()
                    .map(|&[r, g, b]| Vec4::new(r, g, b, 0.0))
                    .collect()
            }),
        }
    }

    /// The identity sensor (pbrt-v4's defaults).
    pub fn identity() -> Sensor {
        Sensor::new(&SensorDesc::default(), 1.0)
    }

    /// What the film takes of a spectral sample's radiance `l` at wavelengths `w`: its
    /// linear sRGB, or a named camera's raw RGB (through the camera's own curves, as pbrt-v4
    /// records a spectral sample); [`Sensor::respond`] takes it from there.
    pub fn sample(&self, l: Color, w: &Wavelengths) -> Color {
        match &self.curves {
            Some(curves) => w.through(l, curves),
            None => w.to_rgb(l),
        }
    }

    /// What the sensor records of a sample's radiance `l`: linear sRGB, or for a named
    /// camera the raw RGB [`Sensor::sample`] gives if `raw` (a spectral sample).
    pub fn respond(&self, l: Color, raw: bool) -> Color {
        let mut l = l * self.ratio;
        if let Some((to_raw, to_image)) = &self.camera {
            let mut raw = if raw {
                rgb_vec(l)
            } else {
                Vec3A::from(to_raw.raw(rgb_of(l)))
            };
            let m = raw.max_element();
            if m > self.max_component {
                raw *= self.max_component / m;
            }
            return vec_rgb(*to_image * raw);
        }
        if self.max_component.is_finite() {
            let m = (self.to_xyz * rgb_vec(l)).max_element();
            if m > self.max_component {
                l *= self.max_component / m;
            }
        }
        match &self.balance {
            Some(b) => vec_rgb(*b * rgb_vec(l)),
            None => l,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_scales_clamps_in_xyz_and_defaults_change_nothing() {
        let l = crate::math::rgb3(0.3, 2.0, 0.7);
        assert_eq!(Sensor::identity().respond(l, false), l);
        let iso = Sensor::new(
            &SensorDesc {
                iso: 400.0,
                ..SensorDesc::default()
            },
            0.5,
        );
        assert!((iso.respond(l, false) - l * 2.0).abs().max_element() < 1e-6);
        let clamp = Sensor::new(
            &SensorDesc {
                max_component: 1.0,
                ..SensorDesc::default()
            },
            1.0,
        );
        let out = clamp.respond(l * 10.0, false);
        let xyz = mat(SRGB_TO_XYZ) * rgb_vec(out);
        assert!((xyz.max_element() - 1.0).abs() < 1e-5, "{xyz}");
        // The clamp keeps the colour: a scaled copy of the input.
        let k = out.y / l.y;
        assert!((out - l * k).abs().max_element() < 1e-5);
        assert_eq!(clamp.respond(l * 0.1, false), l * 0.1);
    }

    /// A camera whose curves are the film's own sRGB response (a mixture of the CIE
    /// observer) records a spectral sample through its curves as the observer does: its raw
    /// RGB is the sample's sRGB and its fitted matrix the identity. So the curves are read at
    /// the sample's wavelengths, in the units the matrix expects.
    #[test]
    fn a_spectral_sample_goes_through_a_named_cameras_curves() {
        use kiln_scene::files::sensor_curves::SensorCurves;
        let response = kiln_scene::spectrum::srgb_response_per_nm();
        let curves = SensorCurves {
            samples: response
                .iter()
                .enumerate()
                .map(|(i, v)| (360.0 + i as f64, [v[0], v[1], v[2]]))
                .collect(),
            path: "srgb.json".into(),
        };
        let camera =
            kiln_scene::camera_sensor::camera_response("srgb", &curves, 6500.0, None).unwrap();
        let sensor = Sensor::new(
            &SensorDesc {
                white_balance: 6500.0,
                camera: Some(camera),
                ..SensorDesc::default()
            },
            1.0,
        );
        let observer = Sensor::identity();
        for k in 0..64 {
            let w = Wavelengths::sample((k as f32 + 0.5) / 64.0);
            let l = w.illuminant(Vec4::new(0.9, 0.4, 0.1, 0.4)) + w.d65() * 0.2;
            let want = observer.respond(observer.sample(l, &w), true);
            let got = sensor.respond(sensor.sample(l, &w), true);
            let scale = want.abs().max_element();
            assert!(
                (got - want).abs().max_element() < 2e-3 * scale,
                "λ {}: {got} vs {want}",
                w.lambda
            );
        }
    }
}
