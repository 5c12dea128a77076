//! A camera's measured spectral response (the `sensor` of pbrt-v4's film): three curves,
//! red, green and blue, read from a JSON file in the layout of Weta Digital's PhysLight
//! camera data (github.com/wetadigital/physlight, `data/camera`, Apache-2.0):
//!
//! ```json
//! {"spectral_data": {"index": {"main": ["R", "G", "B"]},
//!                    "data": {"main": {"380": [0.001, 0.002, 0.002], "385": [...]}}}}
//! ```
//!
//! Kiln ships no camera data. The curves are looked up by sensor name in the folder that
//! [`SENSOR_DATA_ENV`] names: first `NAME.json` (any camera a user measured), then the
//! PhysLight file of the camera pbrt-v4 calls NAME.

use std::path::{Path, PathBuf};

/// The environment variable naming the folder of camera response files.
pub const SENSOR_DATA_ENV: &str = "KILN_SENSOR_DATA";

/// The largest response file read: real ones are a few kilobytes.
const MAX_FILE_BYTES: u64 = 16 << 20;

/// The cameras pbrt-v4 knows by name, with the stems of their PhysLight file names (the
/// files end in `_380_780_5.json`: range and step in nm; either spelling PhysLight used).
pub const PBRT_SENSORS: [(&str, &[&str]); 17] = [
    ("canon_eos_100d", &["Canon_EOS_100D"]),
    (
        "canon_eos_1dx_mkii",
        &["Canon_EOS-1D_X_Mark_II", "Canon_EOS_1DX_Mark_II"],
    ),
    ("canon_eos_200d", &["Canon_EOS_200D"]),
    ("canon_eos_200d_mkii", &["Canon_EOS_200D_II"]),
    ("canon_eos_5d", &["Canon_EOS_5D"]),
    ("canon_eos_5d_mkii", &["Canon_EOS_5D_Mark_II"]),
    ("canon_eos_5d_mkiii", &["Canon_EOS_5D_Mark_III"]),
    ("canon_eos_5d_mkiv", &["Canon_EOS_5D_Mark_IV"]),
    ("canon_eos_5ds", &["Canon_EOS_5DS"]),
    ("canon_eos_m", &["Canon_EOS_M"]),
    ("hasselblad_l1d_20c", &["Hasselblad_L1D-20c"]),
    ("nikon_d810", &["Nikon_D810"]),
    ("nikon_d850", &["Nikon_D850"]),
    ("sony_ilce_6400", &["Sony_ILCE-6400"]),
    ("sony_ilce_7m3", &["Sony_ILCE-7M3"]),
    ("sony_ilce_7rm3", &["Sony_ILCE-7RM3"]),
    ("sony_ilce_9", &["Sony_ILCE-9"]),
];

/// A camera's red, green and blue response, sampled at increasing wavelengths (nm);
/// piecewise linear between samples and zero beyond them, as pbrt-v4 reads its sensor
/// curves.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorCurves {
    pub samples: Vec<(f64, [f64; 3])>,
    /// The file they were read from.
    pub path: PathBuf,
}

/// Finds the response file of sensor `name` in `dir`: `NAME.json`, else the PhysLight file
/// of pbrt-v4's camera of that name. A name may hold only lowercase letters, digits, `_`
/// and `-`, so that no name reaches outside `dir`.
pub fn find_sensor(dir: &Path, name: &str) -> Result<PathBuf, String> {
    let plain = !name.is_empty()
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-');
    if !plain {
        return Err(format!(
            "sensor '{name}' is not a camera name (lowercase letters, digits, '_' and '-')"
        ));
    }
    let own = dir.join(format!("{name}.json"));
    if own.is_file() {
        return Ok(own);
    }
    let stems = PBRT_SENSORS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
        .unwrap_or(&[]);
    let entries = std::fs::read_dir(dir).map_err(|e| {
        format!(
            "cannot read the sensor data folder '{}': {e}",
            dir.display()
        )
    })?;
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            let file = p.file_name().and_then(|f| f.to_str()).unwrap_or("");
            file.ends_with(".json")
                && stems
                    .iter()
                    .any(|s| file.strip_prefix(s).is_some_and(starts_with_range))
        })
        .collect();
    found.sort();
    match found.into_iter().next() {
        Some(p) => Ok(p),
        None if stems.is_empty() => Err(format!(
            "sensor '{name}' is neither a camera pbrt-v4 knows ({}) nor a file '{name}.json' in '{}'",
            PBRT_SENSORS.map(|s| s.0).join(", "),
            dir.display()
        )),
        None => Err(format!(
            "no response file for sensor '{name}' in '{}' (looked for {name}.json and {}_*.json)",
            dir.display(),
            stems.join("_*.json, ")
        )),
    }
}

/// What follows a camera's stem in a PhysLight file name: `_`, then the wavelength range
/// (`_380_780_5.json`), so that one model's stem does not match another's longer name
/// (`Canon_EOS_5D` and `Canon_EOS_5D_Mark_IV`).
fn starts_with_range(rest: &str) -> bool {
    rest.strip_prefix('_')
        .is_some_and(|r| r.starts_with(|c: char| c.is_ascii_digit()))
}

/// Reads a camera response file; errors say what is wrong with it.
pub fn read_sensor_curves(path: &Path) -> Result<SensorCurves, String> {
    let text = super::read_small(path, MAX_FILE_BYTES, "a camera response file")?;
    let samples = parse_sensor_curves(&text).map_err(|e| format!("'{}': {e}", path.display()))?;
    Ok(SensorCurves {
        samples,
        path: path.to_path_buf(),
    })
}

/// The samples of a PhysLight camera file's text.
pub fn parse_sensor_curves(text: &[u8]) -> Result<Vec<(f64, [f64; 3])>, String> {
    use serde_json::Value;
    let root: Value = serde_json::from_slice(text).map_err(|e| format!("not valid JSON: {e}"))?;
    let spectral = root
        .get("spectral_data")
        .ok_or("no \"spectral_data\" object (a PhysLight camera file has one)")?;
    let index = spectral
        .pointer("/index/main")
        .and_then(Value::as_array)
        .ok_or("no \"spectral_data.index.main\" list naming the channels")?;
    let channel = |want: &str| {
        index
            .iter()
            .position(|v| v.as_str().is_some_and(|s| s.eq_ignore_ascii_case(want)))
            .ok_or(format!(
                "\"spectral_data.index.main\" names no {want} channel"
            ))
    };
    let order = [channel("R")?, channel("G")?, channel("B")?];
    let data = spectral
        .pointer("/data/main")
        .and_then(Value::as_object)
        .ok_or("no \"spectral_data.data.main\" object of wavelength: [values]")?;
    let mut samples = Vec::with_capacity(data.len());
    for (key, values) in data {
        let lambda: f64 = key
            .trim()
            .parse()
            .ok()
            .filter(|l: &f64| l.is_finite() && (200.0..=2000.0).contains(l))
            .ok_or(format!(
                "wavelength \"{key}\" is not a number of nanometres (200 to 2000)"
            ))?;
        let values = values
            .as_array()
            .filter(|v| v.len() == index.len())
            .ok_or(format!(
                "the values at {key} nm are not a list of {} numbers",
                index.len()
            ))?;
        let mut rgb = [0.0; 3];
        for (c, &i) in order.iter().enumerate() {
            rgb[c] = values[i]
                .as_f64()
                .filter(|v| v.is_finite())
                .ok_or(format!("a value at {key} nm is not a finite number"))?;
        }
        samples.push((lambda, rgb));
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    if samples.len() < 2 {
        return Err("a response needs at least two wavelengths".into());
    }
    if let Some(w) = samples.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(format!("wavelength {} nm is given twice", w[0].0));
    }
    for (c, name) in ["red", "green", "blue"].iter().enumerate() {
        if samples.iter().map(|s| s.1[c]).sum::<f64>() <= 0.0 {
            return Err(format!("the {name} response is nowhere positive"));
        }
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"header": {"model": "test"}, "spectral_data": {"units": "relative",
        "index": {"main": ["B", "G", "R"]},
        "data": {"main": {"400": [0.5, 0.1, 0.0], "380": [0.2, 0.0, 0.0], "700": [0.0, 0.1, 0.9]}}}}"#;

    #[test]
    fn reads_physlight_layout_in_any_channel_order() {
        let s = parse_sensor_curves(GOOD.as_bytes()).unwrap();
        assert_eq!(
            s,
            vec![
                (380.0, [0.0, 0.0, 0.2]),
                (400.0, [0.0, 0.1, 0.5]),
                (700.0, [0.9, 0.1, 0.0])
            ]
        );
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        let cases = [
            ("{", "not valid JSON"),
            ("{}", "spectral_data"),
            (r#"{"spectral_data": {}}"#, "index.main"),
            (
                r#"{"spectral_data": {"index": {"main": ["R", "G"]}}}"#,
                "no B channel",
            ),
            (
                r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"x": [1,1,1], "500": [1,1,1]}}}}"#,
                "wavelength \"x\"",
            ),
            (
                r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [1,1], "500": [1,1,1]}}}}"#,
                "list of 3 numbers",
            ),
            (
                r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [1,"a",1], "500": [1,1,1]}}}}"#,
                "not a finite number",
            ),
            (
                r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [1,1,1]}}}}"#,
                "at least two",
            ),
            (
                r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [1,1,1], "400.0": [1,1,1]}}}}"#,
                "given twice",
            ),
            (
                r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [1,0,1], "500": [1,0,1]}}}}"#,
                "green response",
            ),
        ];
        for (text, want) in cases {
            let err = parse_sensor_curves(text.as_bytes()).unwrap_err();
            assert!(err.contains(want), "{text}: {err}");
        }
    }

    #[test]
    fn finds_own_and_physlight_files_and_refuses_paths() {
        let dir = std::env::temp_dir().join(format!("kiln-sensors-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("Canon_EOS_5D_Mark_IV_380_780_5.json"), GOOD).unwrap();
        std::fs::write(dir.join("my_camera.json"), GOOD).unwrap();
        assert_eq!(
            find_sensor(&dir, "canon_eos_5d_mkiv").unwrap(),
            dir.join("Canon_EOS_5D_Mark_IV_380_780_5.json")
        );
        // "Canon_EOS_5D" begins the Mark IV's file name too: it is not the 5D's file.
        assert!(find_sensor(&dir, "canon_eos_5d").is_err());
        std::fs::write(dir.join("Canon_EOS_5D_380_780_5.json"), GOOD).unwrap();
        assert_eq!(
            find_sensor(&dir, "canon_eos_5d").unwrap(),
            dir.join("Canon_EOS_5D_380_780_5.json")
        );
        assert_eq!(
            find_sensor(&dir, "my_camera").unwrap(),
            dir.join("my_camera.json")
        );
        let missing = find_sensor(&dir, "nikon_d850").unwrap_err();
        assert!(missing.contains("Nikon_D850_*.json"), "{missing}");
        let unknown = find_sensor(&dir, "brownie").unwrap_err();
        assert!(unknown.contains("canon_eos_100d"), "{unknown}");
        for hostile in ["../etc/passwd", "a/b", "", "Canon"] {
            let e = find_sensor(&dir, hostile).unwrap_err();
            assert!(e.contains("not a camera name"), "{hostile}: {e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
