//! pbrt-v4's "curve" shape: control points in the Bézier or uniform b-spline basis, turned
//! into cubic Bézier segments with their widths and (for ribbons) normals.

use crate::description::{CurveData, CurveType};
use crate::error::{Loc, Result, SceneError};
use crate::params::ParamSet;
use glam::Vec3;

/// pbrt-v4's "curve": control points "P" in the "bezier" or uniform "bspline" basis of
/// "degree" 2 or 3, all turned into cubic Bézier segments; "width" (or "width0" and
/// "width1", spread linearly over the segments), "type" flat, cylinder or ribbon (ribbons
/// need a normal "N" at each segment end), "splitdepth".
pub(super) fn curve_from_params(params: &ParamSet, loc: &Loc) -> Result<CurveData> {
    let at = |name: &str| params.loc_of(name).unwrap_or_else(|| loc.clone());
    let segments = segments(params, loc)?;
    let count = segments.len();
    let widths = widths(params, count, loc)?;
    let kind = match params.string("type")?.as_deref().unwrap_or("flat") {
        "flat" => CurveType::Flat,
        "cylinder" => CurveType::Cylinder,
        "ribbon" => CurveType::Ribbon,
        other => {
            return Err(SceneError::at(
                &at("type"),
                format!("curve: \"type\" must be flat, cylinder or ribbon, got \"{other}\""),
            ));
        }
    };
    let normals = match (params.point3s("N")?, kind) {
        (Some(ns), CurveType::Ribbon) => {
            if ns.len() != count + 1 {
                return Err(SceneError::at(
                    &at("N"),
                    format!(
                        "curve: a ribbon of {count} segments needs {} normals, got {}",
                        count + 1,
                        ns.len()
                    ),
                ));
            }
            Some((0..count).map(|s| [ns[s], ns[s + 1]]).collect())
        }
        (None, CurveType::Ribbon) => {
            return Err(SceneError::at(
                loc,
                "curve: a \"ribbon\" needs normals \"N\" at its segment ends",
            ));
        }
        // pbrt-v4 ignores normals on other types, with a warning.
        (_, _) => None,
    };
    let split_depth = params.int("splitdepth", 3)?;
    if !(0..=8).contains(&split_depth) {
        return Err(SceneError::at(
            &at("splitdepth"),
            format!("curve: \"splitdepth\" must be 0 to 8, got {split_depth}"),
        ));
    }
    if let Some(i) = segments.iter().flatten().position(|p| !p.is_finite()) {
        return Err(SceneError::at(
            &at("P"),
            format!("curve: control point {i} is not finite"),
        ));
    }
    Ok(CurveData {
        segments: segments.iter().map(|s| s.map(|p| p.to_array())).collect(),
        widths,
        normals,
        kind,
        split_depth: split_depth as u32,
    })
}

/// The curve's segments as cubic Bézier control points, from "P", "degree" and "basis".
fn segments(params: &ParamSet, loc: &Loc) -> Result<Vec<[Vec3; 4]>> {
    let at = |name: &str| params.loc_of(name).unwrap_or_else(|| loc.clone());
    let cp = params
        .point3s("P")?
        .ok_or_else(|| SceneError::at(loc, "curve: \"point3 P\" is required"))?;
    let degree = params.int("degree", 3)?;
    if degree != 2 && degree != 3 {
        return Err(SceneError::at(
            &at("degree"),
            format!("curve: \"degree\" must be 2 or 3, got {degree}"),
        ));
    }
    let d = degree as usize;
    let basis = params.string("basis")?.unwrap_or_else(|| "bezier".into());
    let n = cp.len();
    let v = |p: [f32; 3]| Vec3::from(p);
    Ok(match basis.as_str() {
        "bezier" => {
            if n < d + 1 || (n - 1) % d != 0 {
                return Err(SceneError::at(
                    &at("P"),
                    format!(
                        "curve: {n} control points do not make degree-{d} Bézier segments ({} + k·{d} are needed)",
                        d + 1
                    ),
                ));
            }
            (0..(n - 1) / d)
                .map(|s| {
                    let p = &cp[s * d..];
                    if d == 3 {
                        [v(p[0]), v(p[1]), v(p[2]), v(p[3])]
                    } else {
                        elevate([v(p[0]), v(p[1]), v(p[2])])
                    }
                })
                .collect()
        }
        "bspline" => {
            if n < d + 1 {
                return Err(SceneError::at(
                    &at("P"),
                    format!(
                        "curve: a degree-{d} b-spline needs at least {} control points, got {n}",
                        d + 1
                    ),
                ));
            }
            (0..n - d)
                .map(|s| bspline_segment(&cp[s..], d, v))
                .collect()
        }
        other => {
            return Err(SceneError::at(
                &at("basis"),
                format!("curve: \"basis\" must be \"bezier\" or \"bspline\", got \"{other}\""),
            ));
        }
    })
}

/// The Bézier points of the uniform b-spline segment of degree `d` starting at `p`.
fn bspline_segment(p: &[[f32; 3]], d: usize, v: impl Fn([f32; 3]) -> Vec3) -> [Vec3; 4] {
    if d == 3 {
        // The uniform cubic b-spline segment's Bézier points.
        let (p0, p1, p2, p3) = (v(p[0]), v(p[1]), v(p[2]), v(p[3]));
        let (p01, p12, p23) = (
            p0.lerp(p1, 2.0 / 3.0),
            p1.lerp(p2, 1.0 / 3.0),
            p2.lerp(p3, 1.0 / 3.0),
        );
        let p012 = p1.lerp(p2, 2.0 / 3.0);
        [p01.lerp(p12, 0.5), p12, p012, p012.lerp(p23, 0.5)]
    } else {
        let (p0, p1, p2) = (v(p[0]), v(p[1]), v(p[2]));
        elevate([p0.lerp(p1, 0.5), p1, p1.lerp(p2, 0.5)])
    }
}

/// Each segment's widths at its two ends: "width0" to "width1" ("width" both by default)
/// spread linearly over the segments.
fn widths(params: &ParamSet, count: usize, loc: &Loc) -> Result<Vec<[f32; 2]>> {
    let width = params.float("width", 1.0)?;
    let (w0, w1) = (
        params.float("width0", width)?,
        params.float("width1", width)?,
    );
    if !(w0 >= 0.0 && w1 >= 0.0 && w0.is_finite() && w1.is_finite()) {
        return Err(SceneError::at(
            loc,
            "curve: widths must be non-negative numbers",
        ));
    }
    Ok((0..count)
        .map(|s| {
            let f = |k: usize| (w0 + (w1 - w0) * k as f64 / count as f64) as f32;
            [f(s), f(s + 1)]
        })
        .collect())
}

/// The cubic Bézier control points of a quadratic Bézier curve.
fn elevate(p: [Vec3; 3]) -> [Vec3; 4] {
    [
        p[0],
        p[0].lerp(p[1], 2.0 / 3.0),
        p[2].lerp(p[1], 2.0 / 3.0),
        p[2],
    ]
}
