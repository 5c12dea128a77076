//! Spectrum files, pbrt-v4's `.spd` (whitespace-separated wavelength and value pairs, `#`
//! comments), and the folder of measured spectra a user may give in place of pbrt-v4's
//! named ones.
//!
//! Kiln knows pbrt-v4's named spectra (`metal-Au-eta`, `glass-BK7`, ...) by their colour,
//! or by a formula or table of its own where it has one: pbrt-v4's measured tables are not
//! Kiln's to copy. A colour cannot hold a spectrum's shape, and where the shape matters (a
//! gold surface seen through a camera's curves) the images differ. A user who has the
//! measurements puts them in the folder [`SPECTRUM_DATA_ENV`] names, one `NAME.spd` a
//! spectrum (`metal-Au-eta.spd`), and Kiln then reads that spectrum as the table it is,
//! its end values carried on beyond its ends as pbrt-v4 carries its named spectra's.

use crate::error::{Loc, Result, SceneError};
use crate::spectrum::{LAMBDA_MAX, LAMBDA_MIN};
use std::path::PathBuf;

/// The environment variable naming the folder of measured named spectra.
pub const SPECTRUM_DATA_ENV: &str = "KILN_SPECTRUM_DATA";

/// The file in the spectrum data folder that holds named spectrum `name`, if the folder is
/// set and holds one. `name` must be one of the built-in names, which reach no other folder.
pub fn named_spectrum_file(name: &str) -> Option<PathBuf> {
    let dir = std::env::var_os(SPECTRUM_DATA_ENV).filter(|d| !d.is_empty())?;
    let plain = name
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    let path = PathBuf::from(dir).join(format!("{name}.spd"));
    (plain && path.is_file()).then_some(path)
}

/// The numbers of a spectrum file's text, checked to be (wavelength, value) pairs; errors
/// name the file (`file`, as the scene wrote it), its line and the directive's location.
pub fn spd_values(text: &str, file: &str, loc: &Loc) -> Result<Vec<f64>> {
    let mut values = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for word in line.split_whitespace() {
            let v: f64 = word
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    SceneError::at(
                        loc,
                        format!(
                            "spectrum file '{file}', line {}: '{word}' is not a number",
                            i + 1
                        ),
                    )
                })?;
            values.push(v);
        }
    }
    if values.len() < 2 || values.len() % 2 != 0 {
        return Err(SceneError::at(
            loc,
            format!(
                "spectrum file '{file}' holds {} numbers; it needs (wavelength, value) pairs",
                values.len()
            ),
        ));
    }
    Ok(values)
}

/// `pairs` (flattened wavelength, value) with its end values carried on to the visible
/// range's ends, so that a table read as zero beyond its ends reads as a named spectrum.
pub fn carried_to_ends(mut pairs: Vec<f64>) -> Vec<f64> {
    let n = pairs.len();
    let (first, first_v) = (pairs[0], pairs[1]);
    let (last, last_v) = (pairs[n - 2], pairs[n - 1]);
    if last < LAMBDA_MAX {
        pairs.extend([LAMBDA_MAX, last_v]);
    }
    if first > LAMBDA_MIN {
        pairs.splice(0..0, [LAMBDA_MIN, first_v]);
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spd_files_are_pairs_and_errors_say_where() {
        let loc = Loc::synthetic("t");
        assert_eq!(
            spd_values("# gold\n400 0.5\n500 1.5 # end\n", "a.spd", &loc).unwrap(),
            vec![400.0, 0.5, 500.0, 1.5]
        );
        let e = spd_values("400 0.5\n500 x\n", "a.spd", &loc).unwrap_err();
        assert!(e.to_string().contains("'a.spd', line 2: 'x'"), "{e}");
        let e = spd_values("400 0.5 500\n", "a.spd", &loc).unwrap_err();
        assert!(e.to_string().contains("holds 3 numbers"), "{e}");
    }

    #[test]
    fn named_tables_carry_their_ends_on() {
        assert_eq!(
            carried_to_ends(vec![400.0, 0.5, 500.0, 1.5]),
            vec![LAMBDA_MIN, 0.5, 400.0, 0.5, 500.0, 1.5, LAMBDA_MAX, 1.5]
        );
        let wide = vec![300.0, 1.0, 900.0, 2.0];
        assert_eq!(carried_to_ends(wide.clone()), wide);
    }
}
