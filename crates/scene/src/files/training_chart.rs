//! A colour chart's measured reflectances, on which a named camera's raw-to-XYZ matrix is
//! fitted in place of Kiln's own training spectra (`camera_sensor`).
//!
//! pbrt-v4 fits its cameras on the 24 patches of a ColorChecker measured by BabelColor,
//! data Kiln may not copy. A user who has such measurements puts them in the sensor data
//! folder as [`TRAINING_CHART_FILE`], a CSV file: a wavelength in nanometres, then one
//! reflectance a patch, on each line; an optional first line of names; `#` starts a comment.
//! colour-science (PyPI `colour-science`, BSD-3) writes one:
//!
//! ```python
//! import colour
//! colour.write_sds_to_csv_file(colour.SDS_COLOURCHECKERS["BabelColor Average"], "training-chart.csv")
//! ```
//!
//! Between its lines a reflectance is linear, and beyond the first and last wavelength it
//! is zero, as pbrt-v4 reads its own chart (which ends at 730 nm).

use std::path::{Path, PathBuf};

/// The chart's file name in the sensor data folder.
pub const TRAINING_CHART_FILE: &str = "training-chart.csv";

/// The largest chart read: a chart of a thousand patches at 1 nm is some 3 MB.
const MAX_FILE_BYTES: u64 = 16 << 20;

/// The most patches a chart may have: each is evaluated on the fit's 471 wavelengths, so
/// that a one-line file of millions of values cannot ask for gigabytes (real charts have 24
/// to a few hundred).
pub const MAX_PATCHES: usize = 4096;

/// Patches' reflectances sampled at increasing wavelengths.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingChart {
    /// Wavelengths in nm, strictly increasing.
    pub lambdas: Vec<f64>,
    /// Each patch's reflectance at `lambdas`.
    pub patches: Vec<Vec<f64>>,
    /// The file they were read from.
    pub path: PathBuf,
}

impl TrainingChart {
    /// Patch `k`'s reflectance at `lambda`: linear between samples, zero beyond them.
    pub fn reflectance(&self, k: usize, lambda: f64) -> f64 {
        let (l, r) = (&self.lambdas, &self.patches[k]);
        if lambda < l[0] || lambda > l[l.len() - 1] {
            return 0.0;
        }
        let j = l.partition_point(|&x| x <= lambda).clamp(1, l.len() - 1);
        let u = ((lambda - l[j - 1]) / (l[j] - l[j - 1])).clamp(0.0, 1.0);
        r[j - 1] + (r[j] - r[j - 1]) * u
    }
}

/// Reads the chart at `path`; errors name the file and the line.
pub fn read_training_chart(path: &Path) -> Result<TrainingChart, String> {
    let text = super::read_small(path, MAX_FILE_BYTES, "a training chart")?;
    let (lambdas, patches) =
        parse_training_chart(&text).map_err(|e| format!("'{}': {e}", path.display()))?;
    Ok(TrainingChart {
        lambdas,
        patches,
        path: path.to_path_buf(),
    })
}

/// The wavelengths and each patch's reflectances of a chart file's text.
pub fn parse_training_chart(text: &[u8]) -> Result<(Vec<f64>, Vec<Vec<f64>>), String> {
    let text = std::str::from_utf8(text).map_err(|_| "not UTF-8 text".to_string())?;
    let mut lambdas = Vec::new();
    let mut patches: Vec<Vec<f64>> = Vec::new();
    let mut header_allowed = true;
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let first = fields[0].trim_matches('"');
        if header_allowed && first.parse::<f64>().is_err() {
            header_allowed = false;
            continue;
        }
        header_allowed = false;
        let lambda: f64 = first
            .parse()
            .ok()
            .filter(|l: &f64| l.is_finite() && (200.0..=2000.0).contains(l))
            .ok_or(format!(
                "line {line_no}: \"{first}\" is not a wavelength in nanometres (200 to 2000)"
            ))?;
        if let Some(&last) = lambdas.last()
            && lambda <= last
        {
            return Err(format!(
                "line {line_no}: wavelength {lambda} nm does not follow {last} nm (wavelengths must increase)"
            ));
        }
        let values = &fields[1..];
        if patches.is_empty() {
            if values.len() < 3 || values.len() > MAX_PATCHES {
                return Err(format!(
                    "line {line_no}: {} reflectances; a chart has 3 to {MAX_PATCHES} patches",
                    values.len()
                ));
            }
            patches = vec![Vec::new(); values.len()];
        } else if values.len() != patches.len() {
            return Err(format!(
                "line {line_no}: {} reflectances where the first line had {}",
                values.len(),
                patches.len()
            ));
        }
        for (k, v) in values.iter().enumerate() {
            let r: f64 = v
                .parse()
                .ok()
                .filter(|r: &f64| r.is_finite() && (0.0..=10.0).contains(r))
                .ok_or(format!(
                    "line {line_no}, patch {}: \"{v}\" is not a reflectance (a number from 0 to 10)",
                    k + 1
                ))?;
            patches[k].push(r);
        }
        lambdas.push(lambda);
    }
    if lambdas.len() < 2 {
        return Err("a chart needs reflectances at two wavelengths at least".into());
    }
    Ok((lambdas, patches))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_colour_sciences_layout_and_interpolates() {
        let text = "wavelength,dark skin,light skin,blue sky\n\
                    # a comment\n\
                    400, 0.1, 0.2, 0.3\n\
                    \n\
                    500,0.3,0.2,0.1 # trailing\n";
        let (l, p) = parse_training_chart(text.as_bytes()).unwrap();
        assert_eq!(l, vec![400.0, 500.0]);
        assert_eq!(p, vec![vec![0.1, 0.3], vec![0.2, 0.2], vec![0.3, 0.1]]);
        let chart = TrainingChart {
            lambdas: l,
            patches: p,
            path: "c.csv".into(),
        };
        assert_eq!(chart.reflectance(0, 399.9), 0.0);
        assert_eq!(chart.reflectance(0, 500.1), 0.0);
        assert_eq!(chart.reflectance(0, 400.0), 0.1);
        assert_eq!(chart.reflectance(2, 500.0), 0.1);
        assert!((chart.reflectance(0, 450.0) - 0.2).abs() < 1e-15);
        // No header line is needed either.
        assert!(parse_training_chart(b"400,1,1,1\n410,1,1,1").is_ok());
    }

    #[test]
    fn bad_charts_say_where() {
        let too_many = format!("400{}\n500,1", ",0".repeat(MAX_PATCHES + 1));
        let cases = [
            ("400,1,1\n500,1,1", "line 1: 2 reflectances"),
            (too_many.as_str(), "line 1: 4097 reflectances"),
            ("w,a,b,c\n400,1,1,1\n390,1,1,1", "line 3: wavelength 390"),
            ("400,1,1,1\n500,1,1", "line 2: 2 reflectances where"),
            ("400,1,1,1\n500,1,x,1", "line 2, patch 2: \"x\""),
            ("400,1,1,1\n500,1,-0.5,1", "patch 2"),
            ("400,1,1,1\nNaN,1,1,1", "line 2: \"NaN\""),
            ("400,1,1,1\n5000,1,1,1", "line 2: \"5000\""),
            ("w,a,b,c\n400,1,1,1", "two wavelengths"),
            ("a,b\nc,d,e", "line 2: \"c\""),
        ];
        for (text, want) in cases {
            let err = parse_training_chart(text.as_bytes()).unwrap_err();
            assert!(err.contains(want), "{text:?}: {err}");
        }
        assert!(
            parse_training_chart(&[0xff, 0xfe])
                .unwrap_err()
                .contains("UTF-8")
        );
    }
}
