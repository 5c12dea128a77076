//! pbrt's graphics state: the current transform (and which of the start and end
//! transforms directives change), named coordinate systems, the attribute stack, the
//! current material and media chosen by name, and object instancing.

use super::Parser;
use super::cursor::Cursor;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::lexer::TokenKind;
use crate::params::ParamSet;
use glam::{DMat4, DVec3, DVec4};

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum ActiveTransform {
    Start,
    End,
    All,
}

#[derive(Clone)]
pub(super) struct GraphicsState {
    /// The current transform at the shutter's opening (what Kiln renders with).
    pub(super) ctm: DMat4,
    /// The current transform at its closing: where it differs from `ctm`, pbrt-v4 would
    /// blur the motion, which Kiln does not render yet.
    pub(super) ctm_end: DMat4,
    pub(super) active: ActiveTransform,
    pub(super) reverse_orientation: bool,
    pub(super) material: MaterialId,
    pub(super) area_light: Option<AreaLightDesc>,
    /// Names of the current inside and outside media ("" is vacuum).
    pub(super) media: (String, String),
    /// pbrt-v4's `Attribute` defaults, per target (shape, light, material, medium,
    /// texture), in the order of [`ATTRIBUTE_TARGETS`].
    pub(super) attributes: [Vec<crate::params::Param>; 5],
    /// pbrt-v4's ColorSpace: the space later `rgb` values are in.
    pub(super) color_space: crate::colorspace::ColorSpace,
}

/// What an `Attribute` directive may give defaults to.
pub(super) const ATTRIBUTE_TARGETS: [&str; 5] = ["shape", "light", "material", "medium", "texture"];

impl Parser {
    pub(super) fn apply_transform(&mut self, m: DMat4) {
        if self.gs.active != ActiveTransform::End {
            self.gs.ctm *= m;
        }
        if self.gs.active != ActiveTransform::Start {
            self.gs.ctm_end *= m;
        }
    }

    /// Sets the current transform, at the start or end time or both as ActiveTransform says.
    fn set_transform(&mut self, m: DMat4) {
        if self.gs.active != ActiveTransform::End {
            self.gs.ctm = m;
        }
        if self.gs.active != ActiveTransform::Start {
            self.gs.ctm_end = m;
        }
    }

    /// The end transform, where it differs from the start one (the current transform moves).
    pub(super) fn moving_end(&self) -> Option<DMat4> {
        let (a, b) = (self.gs.ctm, self.gs.ctm_end);
        let scale = a.to_cols_array().iter().fold(1.0f64, |m, v| m.max(v.abs()));
        let moves = a
            .to_cols_array()
            .iter()
            .zip(b.to_cols_array())
            .any(|(x, y)| (x - y).abs() > 1e-9 * scale);
        moves.then_some(b)
    }

    /// Where the current transform moves during the shutter interval, a warning that
    /// `what` stays at its start transform: pbrt-v4 moves no light and no medium either (it
    /// warns and uses the start), so the image is pbrt-v4's.
    pub(super) fn still_at_start(&mut self, loc: &Loc, what: &str) {
        if self.moving_end().is_some() {
            self.warn(
                loc,
                format!(
                    "{what}: its transform differs between the shutter's start and end (ActiveTransform); it stays at its start transform, as pbrt-v4 keeps lights and media still"
                ),
            );
        }
    }

    pub(super) fn medium_id(&self, name: &str) -> Option<MediumId> {
        (!name.is_empty()).then(|| self.named_media[name])
    }

    pub(super) fn identity(&mut self) {
        self.set_transform(DMat4::IDENTITY);
    }

    pub(super) fn translate(&mut self, c: &mut Cursor) -> Result<()> {
        let v = c.numbers("Translate", 3)?;
        self.apply_transform(DMat4::from_translation(DVec3::new(v[0], v[1], v[2])));
        Ok(())
    }

    pub(super) fn scale(&mut self, c: &mut Cursor) -> Result<()> {
        let v = c.numbers("Scale", 3)?;
        self.apply_transform(DMat4::from_scale(DVec3::new(v[0], v[1], v[2])));
        Ok(())
    }

    pub(super) fn rotate(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let v = c.numbers("Rotate", 4)?;
        let axis = DVec3::new(v[1], v[2], v[3]).normalize_or_zero();
        if axis == DVec3::ZERO {
            return Err(SceneError::at(
                loc,
                "Rotate about a zero-length axis (or one too long to normalise)",
            ));
        }
        self.apply_transform(DMat4::from_axis_angle(axis, v[0].to_radians()));
        Ok(())
    }

    pub(super) fn look_at(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let v = c.numbers("LookAt", 9)?;
        let m = look_at_matrix(
            DVec3::new(v[0], v[1], v[2]),
            DVec3::new(v[3], v[4], v[5]),
            DVec3::new(v[6], v[7], v[8]),
        )
        .ok_or_else(|| {
            SceneError::at(
                loc,
                "LookAt: eye and target coincide, or 'up' is parallel to the view direction",
            )
        })?;
        self.apply_transform(m);
        Ok(())
    }

    /// `Transform` replaces the current transform, `ConcatTransform` multiplies it.
    pub(super) fn transform(&mut self, directive: &str, c: &mut Cursor) -> Result<()> {
        let v = c.numbers(directive, 16)?;
        let mut a = [0.0; 16];
        a.copy_from_slice(&v);
        // pbrt lists the matrix column by column, as glam stores it.
        let m = DMat4::from_cols_array(&a);
        if directive == "Transform" {
            self.set_transform(m);
        } else {
            self.apply_transform(m);
        }
        Ok(())
    }

    pub(super) fn coordinate_system(&mut self, c: &mut Cursor) -> Result<()> {
        let name = c.string("CoordinateSystem", "name")?;
        self.named_coordinate_systems
            .insert(name, (self.gs.ctm, self.gs.ctm_end));
        Ok(())
    }

    pub(super) fn coord_sys_transform(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let name = c.string("CoordSysTransform", "name")?;
        match self.named_coordinate_systems.get(&name) {
            Some(&(start, end)) => {
                self.gs.ctm = start;
                self.gs.ctm_end = end;
            }
            // pbrt-v4 warns and keeps the current transform; so does Kiln.
            None => self.warn(
                loc,
                format!(
                    "CoordSysTransform: no coordinate system named '{name}'; the transform is left as it was (as pbrt-v4 does)"
                ),
            ),
        }
        Ok(())
    }

    pub(super) fn active_transform(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let which = match c.peek().map(|t| &t.kind) {
            Some(TokenKind::Word(w)) => w.clone(),
            _ => {
                return Err(SceneError::at(
                    loc,
                    "ActiveTransform needs StartTime, EndTime or All",
                ));
            }
        };
        c.pos += 1;
        self.gs.active = match which.as_str() {
            "StartTime" => ActiveTransform::Start,
            "EndTime" => ActiveTransform::End,
            "All" => ActiveTransform::All,
            _ => {
                return Err(SceneError::at(
                    loc,
                    format!("ActiveTransform: unknown '{which}'"),
                ));
            }
        };
        Ok(())
    }

    pub(super) fn transform_times(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let t = c.numbers("TransformTimes", 2)?;
        if !(t[0].is_finite() && t[1].is_finite() && t[1] >= t[0]) {
            return Err(SceneError::at(
                loc,
                format!(
                    "TransformTimes: the end time {} must not come before the start time {}",
                    t[1], t[0]
                ),
            ));
        }
        self.transform_times = [t[0], t[1]];
        Ok(())
    }

    /// `Attribute "target" params...`: defaults for the parameters of later shapes, lights,
    /// materials, media or textures in this attribute scope; a later value replaces an
    /// earlier one.
    pub(super) fn attribute(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let target = c.string("Attribute", "target")?;
        let Some(i) = ATTRIBUTE_TARGETS.iter().position(|t| *t == target) else {
            return Err(SceneError::at(
                loc,
                format!(
                    "Attribute: unknown target '{target}' (pbrt-v4 has {})",
                    ATTRIBUTE_TARGETS.join(", ")
                ),
            ));
        };
        for param in c.params()?.into_params() {
            let defaults = &mut self.gs.attributes[i];
            defaults.retain(|p| p.name != param.name);
            defaults.push(param);
        }
        Ok(())
    }

    /// A directive's parameters with the `Attribute` defaults of `target` added (moved
    /// through unchanged when there are none: a mesh's arrays are not copied).
    pub(super) fn with_attributes(&self, target: &str, params: ParamSet) -> ParamSet {
        let params = match ATTRIBUTE_TARGETS.iter().position(|t| *t == target) {
            Some(i) if !self.gs.attributes[i].is_empty() => {
                params.with_defaults(&self.gs.attributes[i])
            }
            _ => params,
        };
        params.in_color_space(self.gs.color_space)
    }

    pub(super) fn reverse_orientation(&mut self) {
        self.gs.reverse_orientation = !self.gs.reverse_orientation;
    }

    /// `AttributeBegin` saves the whole graphics state. So does `TransformBegin`: pbrt-v4
    /// reads it as `AttributeBegin` (with a warning that it is deprecated), so a material or
    /// light set inside a TransformBegin/End block ends with it.
    pub(super) fn attribute_begin(&mut self, directive: &str, loc: &Loc) {
        if directive == "TransformBegin" && !self.warned_transform_begin {
            self.warned_transform_begin = true;
            self.warn(
                loc,
                "TransformBegin/End are deprecated: pbrt-v4 reads them as AttributeBegin/End (the whole graphics state is saved and restored), and so does Kiln",
            );
        }
        self.stack.push((self.gs.clone(), loc.clone(), false));
    }

    pub(super) fn attribute_end(&mut self, directive: &str, loc: &Loc) -> Result<()> {
        let Some((saved, _, _)) = self.stack.pop() else {
            return Err(SceneError::at(
                loc,
                format!("{directive} without a matching begin"),
            ));
        };
        self.gs = saved;
        Ok(())
    }

    pub(super) fn medium_interface(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let inside = c.string("MediumInterface", "inside medium name")?;
        // One name means the same medium on both sides.
        let outside = match c.peek().map(|t| &t.kind) {
            Some(TokenKind::Str(_)) => c.string("MediumInterface", "outside medium name")?,
            _ => inside.clone(),
        };
        for name in [&inside, &outside] {
            if !name.is_empty() && !self.named_media.contains_key(name) {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "MediumInterface: no medium named '{name}' (MakeNamedMedium defines one)"
                    ),
                ));
            }
        }
        self.gs.media = (inside, outside);
        Ok(())
    }

    pub(super) fn named_material(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let name = c.string("NamedMaterial", "material name")?;
        match self.named_materials.get(&name) {
            Some(id) => self.gs.material = *id,
            None => {
                return Err(SceneError::at(
                    loc,
                    format!("NamedMaterial: no material named '{name}'"),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn object_begin(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let name = c.string("ObjectBegin", "object name")?;
        if self.current_object.is_some() {
            return Err(SceneError::at(
                loc,
                "ObjectBegin inside another ObjectBegin",
            ));
        }
        self.stack.push((self.gs.clone(), loc.clone(), false));
        self.current_object = Some(ObjectDesc {
            name,
            shapes: Vec::new(),
            loc: loc.clone(),
        });
        Ok(())
    }

    pub(super) fn object_end(&mut self, loc: &Loc) -> Result<()> {
        let Some(object) = self.current_object.take() else {
            return Err(SceneError::at(loc, "ObjectEnd without ObjectBegin"));
        };
        if let Some((saved, _, _)) = self.stack.pop() {
            self.gs = saved;
        }
        if self.object_names.contains_key(&object.name) {
            return Err(SceneError::at(
                loc,
                format!("object '{}' is defined twice", object.name),
            ));
        }
        self.object_names
            .insert(object.name.clone(), self.objects.len());
        self.objects.push(object);
        Ok(())
    }

    pub(super) fn object_instance(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let name = c.string("ObjectInstance", "object name")?;
        let Some(&object) = self.object_names.get(&name) else {
            return Err(SceneError::at(
                loc,
                format!("ObjectInstance: no object named '{name}'"),
            ));
        };
        if self.current_object.is_some() {
            return Err(SceneError::at(
                loc,
                "ObjectInstance inside ObjectBegin is not supported",
            ));
        }
        self.instances.push(InstanceDesc {
            object,
            instance_to_world: self.gs.ctm,
            instance_to_world_end: self.moving_end(),
            loc: loc.clone(),
        });
        Ok(())
    }
}

/// pbrt's LookAt: the camera-from-world transform of a camera at `eye` looking at `target`.
fn look_at_matrix(eye: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - eye).try_normalize()?;
    let right = up.try_normalize()?.cross(dir).try_normalize()?;
    let new_up = dir.cross(right);
    let world_from_camera = DMat4::from_cols(
        right.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        DVec4::new(eye.x, eye.y, eye.z, 1.0),
    );
    Some(world_from_camera.inverse())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parser::tests::load;

    /// pbrt-v4's Attribute: defaults for later shapes (or lights, ...) in the attribute
    /// scope; a parameter given on the shape wins; a default a shape does not use is no
    /// error; an unknown target is.
    #[test]
    fn attributes_give_defaults_in_their_scope() {
        let s = load(
            "WorldBegin
             AttributeBegin
               Attribute \"shape\" \"float radius\" [ 0.5 ]
               Attribute \"light\" \"rgb L\" [ 2 2 2 ]
               Shape \"sphere\"
               Shape \"sphere\" \"float radius\" [ 3 ]
               Shape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ]
               Attribute \"shape\" \"float radius\" [ 0.25 ]
               AreaLightSource \"diffuse\"
               Shape \"sphere\"
             AttributeEnd
             Shape \"sphere\"",
        );
        let radius = |i: usize| match s.shapes[i].kind {
            ShapeKind::Sphere { radius, .. } => radius,
            _ => panic!("shape {i} is a sphere"),
        };
        assert_eq!(radius(0), 0.5);
        assert_eq!(radius(1), 3.0);
        assert_eq!(radius(3), 0.25);
        assert_eq!(radius(4), 1.0, "the attribute ends with its scope");
        match &s.shapes[3].area_light {
            Some(AreaLightDesc::Diffuse { radiance, .. }) => assert_eq!(*radiance, [2.0; 3]),
            other => panic!("{other:?}"),
        }
        let err = crate::parser::load_str(
            "WorldBegin\nAttribute \"camera\" \"float fov\" [ 30 ]\n",
            std::path::Path::new("t.pbrt"),
            std::path::Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("t.pbrt:2") && err.contains("unknown target 'camera'"),
            "{err}"
        );
    }

    #[test]
    fn look_at_puts_the_camera_at_the_eye_looking_at_the_target() {
        let s = load("LookAt 1 2 3  1 2 10  0 1 0\nCamera \"perspective\"\nWorldBegin\n");
        let m = s.camera.camera_to_world;
        assert!((m.transform_point3(DVec3::ZERO) - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-12);
        assert!((m.transform_vector3(DVec3::Z) - DVec3::Z).length() < 1e-12);
        assert!((m.transform_vector3(DVec3::Y) - DVec3::Y).length() < 1e-12);
    }

    #[test]
    fn transform_lists_columns_and_attributes_restore_state() {
        let s = load(
            "WorldBegin
             AttributeBegin
               Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1 ]
               Material \"conductor\"
               Shape \"sphere\"
             AttributeEnd
             Translate 1 0 0
             Rotate 90 0 0 1
             Shape \"sphere\" \"float radius\" [ 2 ]",
        );
        let a = &s.shapes[0];
        assert_eq!(
            a.object_to_world.transform_point3(DVec3::ZERO),
            DVec3::new(5.0, 6.0, 7.0)
        );
        assert!(matches!(
            s.materials[a.material.0 as usize].kind,
            MaterialKind::Conductor { .. }
        ));
        let b = &s.shapes[1];
        assert_eq!(
            b.material,
            MaterialId(0),
            "AttributeEnd restores the default material"
        );
        // Translate then Rotate: points rotate first, then move.
        let p = b.object_to_world.transform_point3(DVec3::X);
        assert!((p - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-12, "{p}");
    }

    #[test]
    fn coordinate_systems_named_materials_and_instances() {
        let s = load(
            "LookAt 0 0 -5  0 0 0  0 1 0
             Camera \"perspective\"
             WorldBegin
             MakeNamedMaterial \"gold\" \"string type\" \"conductor\" \"spectrum eta\" \"metal-Au-eta\" \"spectrum k\" \"metal-Au-k\"
             ObjectBegin \"ball\"
               NamedMaterial \"gold\"
               Translate 0 1 0
               Shape \"sphere\"
             ObjectEnd
             Translate 10 0 0
             ObjectInstance \"ball\"
             CoordSysTransform \"camera\"
             LightSource \"point\" \"rgb I\" [ 1 1 1 ]",
        );
        assert_eq!(s.instances.len(), 1);
        let object = &s.objects[s.instances[0].object];
        let world = s.instances[0].instance_to_world * object.shapes[0].object_to_world;
        assert_eq!(
            world.transform_point3(DVec3::ZERO),
            DVec3::new(10.0, 1.0, 0.0)
        );
        assert_eq!(
            s.materials[object.shapes[0].material.0 as usize]
                .name
                .as_deref(),
            Some("gold")
        );
        let LightKind::Point { position, .. } = s.lights[0].kind else {
            panic!()
        };
        assert!(
            (position - DVec3::new(0.0, 0.0, -5.0)).length() < 1e-12,
            "the light sits at the camera"
        );
    }

    /// TransformBegin/End save and restore the whole graphics state, as pbrt-v4 reads them
    /// (as AttributeBegin/End); an unknown CoordSysTransform keeps the transform, with a
    /// warning, as in pbrt-v4.
    #[test]
    fn transform_blocks_and_unknown_coordinate_systems_behave_as_in_pbrt_v4() {
        let s = crate::parser::tests::load(
            "WorldBegin
             TransformBegin
               Material \"conductor\"
               Translate 1 0 0
             TransformEnd
             Shape \"sphere\"
             CoordSysTransform \"nowhere\"
             Shape \"sphere\"",
        );
        assert!(
            matches!(
                s.materials[s.shapes[0].material.0 as usize].kind,
                MaterialKind::Diffuse { .. }
            ),
            "the material set inside the block ends with it"
        );
        assert_eq!(s.shapes[0].object_to_world, DMat4::IDENTITY);
        assert_eq!(s.shapes[1].object_to_world, DMat4::IDENTITY);
        assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
    }
}
