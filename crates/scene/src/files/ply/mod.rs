//! PLY triangle meshes, read as pbrt-v4's "plymesh" shape reads them: `ascii`,
//! `binary_little_endian` and `binary_big_endian`, from bytes in memory.
//! Only `vertex` and `face` are kept; other elements are still read (binary
//! record sizes must be honoured to find what follows) and dropped. Nothing
//! here panics: every count from the file is checked against the bytes left
//! before it is trusted with an allocation or a loop. [`read_ply`] reads a
//! file into the scene's [`TriangleMeshData`].

use super::read_bytes;
use crate::error::{Loc, Result, SceneError};
use crate::mesh::TriangleMeshData;
use std::path::Path;

/// A triangle mesh read from a PLY file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlyMesh {
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals when the file has nx, ny, nz.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Per-vertex texture coordinates when the file has u/v, s/t or texture_u/texture_v (texture_s/texture_t).
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Triangle vertex indices, three per triangle; polygons of five or more vertices are
    /// fanned around their first.
    pub indices: Vec<u32>,
    /// Quads as pbrt-v4's bilinear patches, four indices each in its corner order p00, p10,
    /// p01, p11 (a face 0,1,2,3 gives 0,1,3,2).
    pub quads: Vec<u32>,
}

/// Why a PLY file could not be read. Every message says where: header and
/// ASCII problems start with the 1-based line ("line 7: ..."); binary body
/// problems name the element and record ("face 1234 ...").
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// The first line is not "ply".
    #[error("line 1: not a PLY file (it does not start with \"ply\")")]
    NotPly,
    /// No "end_header" line at all; `line` is the file's last line.
    #[error("line {line}: the file ends without an \"end_header\" line")]
    MissingEndHeader { line: usize },
    /// A "format" other than ascii, binary_little_endian, binary_big_endian.
    #[error(
        "line {line}: unknown format \"{format}\" (expected ascii, binary_little_endian or binary_big_endian)"
    )]
    UnknownFormat { line: usize, format: String },
    /// A property type that is not one of the eight PLY scalar types.
    #[error("line {line}: unknown property type \"{ty}\"")]
    UnknownType { line: usize, ty: String },
    /// The vertex element, declared on `line`, lacks x, y or z.
    #[error("line {line}: element \"vertex\" has no \"{axis}\" property")]
    MissingPosition { line: usize, axis: &'static str },
    /// Any other malformed header line.
    #[error("line {line}: {message}")]
    Header { line: usize, message: String },
    /// An ASCII token that does not parse as its declared type.
    #[error("line {line}: \"{token}\" is not a valid {ty}")]
    NotANumber {
        line: usize,
        token: String,
        ty: &'static str,
    },
    /// The data stops inside record `index` of `element` (`line` for ASCII).
    #[error("{}file ends in the middle of {element} {index} of {count}", line_prefix(.line))]
    Truncated {
        line: Option<usize>,
        element: String,
        index: usize,
        count: usize,
    },
    /// A face index that is negative or not below the vertex count.
    #[error("{}face {face} refers to vertex {vertex} but there are {vertices} vertices", line_prefix(.line))]
    IndexOutOfRange {
        line: Option<usize>,
        face: usize,
        vertex: i64,
        vertices: usize,
    },
    /// A face with fewer than three vertices.
    #[error("{}face {face} has {count} vertices; a face needs at least 3", line_prefix(.line))]
    TooFewVertices {
        line: Option<usize>,
        face: usize,
        count: u64,
    },
    /// Any other bad value in record `index` of `element`.
    #[error("{}{element} {index}: {message}", line_prefix(.line))]
    Invalid {
        line: Option<usize>,
        element: String,
        index: usize,
        message: String,
    },
}

fn line_prefix(line: &Option<usize>) -> String {
    line.map(|line| format!("line {line}: "))
        .unwrap_or_default()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    const ALL: [Scalar; 8] = [
        Self::I8,
        Self::U8,
        Self::I16,
        Self::U16,
        Self::I32,
        Self::U32,
        Self::F32,
        Self::F64,
    ];

    /// PLY name, sized alias, byte size and, for integers, the value range.
    fn info(self) -> (&'static str, &'static str, usize, Option<(i64, i64)>) {
        match self {
            Self::I8 => ("char", "int8", 1, Some((i8::MIN.into(), i8::MAX.into()))),
            Self::U8 => ("uchar", "uint8", 1, Some((0, u8::MAX.into()))),
            Self::I16 => (
                "short",
                "int16",
                2,
                Some((i16::MIN.into(), i16::MAX.into())),
            ),
            Self::U16 => ("ushort", "uint16", 2, Some((0, u16::MAX.into()))),
            Self::I32 => ("int", "int32", 4, Some((i32::MIN.into(), i32::MAX.into()))),
            Self::U32 => ("uint", "uint32", 4, Some((0, u32::MAX.into()))),
            Self::F32 => ("float", "float32", 4, None),
            Self::F64 => ("double", "float64", 8, None),
        }
    }

    fn from_name(name: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|ty| ty.info().0 == name || ty.info().1 == name)
    }

    fn size(self) -> usize {
        self.info().2
    }

    /// Parses an ASCII token. Integers must be whole and in range, as rply's
    /// strtol checks demand; "3.0" is tolerated since some exporters write it.
    fn parse_text(self, text: &str) -> Option<f64> {
        let Some((lo, hi)) = self.info().3 else {
            return text.parse::<f64>().ok();
        };
        let value = match text.parse::<i64>() {
            Ok(v) => v as f64,
            Err(_) => text.parse::<f64>().ok().filter(|v| v.fract() == 0.0)?,
        };
        ((lo as f64) <= value && value <= (hi as f64)).then_some(value)
    }
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Scalar(Scalar),
    List { len: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

/// One "element" declaration; `line` is where it is declared, for errors.
#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    line: usize,
    props: Vec<Property>,
}

#[derive(Debug, Clone, Copy)]
enum Format {
    Ascii,
    BinaryLittle,
    BinaryBig,
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    end_line: usize,
    body_start: usize,
}

/// Reads a PLY mesh; errors name the directive's location and the file.
pub fn read_ply(path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    let bytes = read_bytes(path, loc)?;
    let mesh = parse_ply(&bytes)
        .map_err(|e| SceneError::at(loc, format!("PLY file '{}': {e}", path.display())))?;
    Ok(TriangleMeshData {
        positions: mesh.positions,
        normals: mesh.normals,
        uvs: mesh.uvs,
        indices: mesh.indices,
        quads: Vec::new(),
    }
    .with_quads(&mesh.quads))
}

/// Reads a PLY file held in memory into a triangle mesh.
///
/// Normals and texture coordinates are returned only when the file has all
/// their components; polygons are triangulated as a fan around their first
/// vertex. Elements other than `vertex` and `face` are skipped.
pub fn parse_ply(bytes: &[u8]) -> Result<PlyMesh, PlyError> {
    let header = parse_header(bytes)?;
    let data = bytes.get(header.body_start..).unwrap_or_default();
    match header.format {
        Format::Ascii => {
            let src = AsciiSource {
                data,
                pos: 0,
                line: header.end_line + 1,
                last_line: header.end_line,
            };
            read_body(&header, src)
        }
        Format::BinaryLittle => read_body(&header, BinarySource::<false> { data, pos: 0 }),
        Format::BinaryBig => read_body(&header, BinarySource::<true> { data, pos: 0 }),
    }
}

fn parse_header(bytes: &[u8]) -> Result<Header, PlyError> {
    let first = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    if first.trim_ascii() != b"ply".as_slice() {
        return Err(PlyError::NotPly);
    }
    // Find the end first, so a header without "end_header" is reported as
    // such rather than as the body's first number being an unknown keyword.
    let (mut lines, mut pos, mut end) = (0usize, 0usize, None);
    for raw in bytes.split_inclusive(|&b| b == b'\n') {
        lines += 1;
        pos += raw.len();
        if raw.trim_ascii() == b"end_header".as_slice() {
            end = Some((lines, pos));
            break;
        }
    }
    let Some((end_line, body_start)) = end else {
        return Err(PlyError::MissingEndHeader { line: lines });
    };

    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let header_lines = bytes.split_inclusive(|&b| b == b'\n').enumerate();
    for (i, raw) in header_lines.take(end_line.saturating_sub(1)).skip(1) {
        let line = i + 1;
        let bad = |message: &str| PlyError::Header {
            line,
            message: message.to_string(),
        };
        let text = std::str::from_utf8(raw).map_err(|_| bad("header line is not valid text"))?;
        let mut words = text.split_ascii_whitespace();
        match words.next() {
            None | Some("comment" | "obj_info") => {}
            Some("format") => {
                let name = words.next().unwrap_or("");
                format = Some(match name {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLittle,
                    "binary_big_endian" => Format::BinaryBig,
                    _ => {
                        return Err(PlyError::UnknownFormat {
                            line,
                            format: name.to_string(),
                        });
                    }
                });
            }
            Some("element") => {
                let (Some(name), Some(count_text)) = (words.next(), words.next()) else {
                    return Err(bad("expected \"element NAME COUNT\""));
                };
                let count = count_text.parse::<usize>().map_err(|_| {
                    bad(&format!(
                        "element count \"{count_text}\" is not a non-negative integer"
                    ))
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    line,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(bad("\"property\" comes before any \"element\""));
                };
                let kind = match words.next() {
                    Some("list") => {
                        let len = scalar_type(words.next(), line)?;
                        let item = scalar_type(words.next(), line)?;
                        if len.info().3.is_none() {
                            return Err(bad(&format!(
                                "list length type \"{}\" is not an integer type",
                                len.info().0
                            )));
                        }
                        Kind::List { len, item }
                    }
                    ty => Kind::Scalar(scalar_type(ty, line)?),
                };
                let Some(name) = words.next() else {
                    return Err(bad("property has no name"));
                };
                element.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            Some(other) => return Err(bad(&format!("unknown header keyword \"{other}\""))),
        }
    }
    let format = format.ok_or_else(|| PlyError::Header {
        line: end_line,
        message: "the header has no \"format\" line".to_string(),
    })?;
    Ok(Header {
        format,
        elements,
        end_line,
        body_start,
    })
}

fn scalar_type(word: Option<&str>, line: usize) -> Result<Scalar, PlyError> {
    let word = word.ok_or_else(|| PlyError::Header {
        line,
        message: "property type is missing".to_string(),
    })?;
    Scalar::from_name(word).ok_or_else(|| PlyError::UnknownType {
        line,
        ty: word.to_string(),
    })
}

/// A failure inside one record; [`body_err`] adds the element, record and line.
enum ReadErr {
    Eof,
    Bad(Box<(usize, String, &'static str)>),
    Invalid(Box<str>),
    TooFew(u64),
    OutOfRange { vertex: i64, vertices: usize },
}

fn body_err(err: ReadErr, line: Option<usize>, el: &Element, index: usize) -> PlyError {
    match err {
        ReadErr::Eof => PlyError::Truncated {
            line,
            element: el.name.clone(),
            index,
            count: el.count,
        },
        ReadErr::Bad(bad) => PlyError::NotANumber {
            line: bad.0,
            token: bad.1,
            ty: bad.2,
        },
        ReadErr::Invalid(message) => PlyError::Invalid {
            line,
            element: el.name.clone(),
            index,
            message: message.into(),
        },
        ReadErr::TooFew(count) => PlyError::TooFewVertices {
            line,
            face: index,
            count,
        },
        ReadErr::OutOfRange { vertex, vertices } => PlyError::IndexOutOfRange {
            line,
            face: index,
            vertex,
            vertices,
        },
    }
}

/// The file body as a stream of values. A trait rather than an enum so the
/// record loops are compiled once per format instead of branching per value.
trait Source {
    const BINARY: bool;
    fn value(&mut self, ty: Scalar) -> Result<f64, ReadErr>;
    fn skip(&mut self, n: u64, ty: Scalar) -> Result<(), ReadErr>;
    fn remaining(&self) -> usize;
    /// The line to report for an error at the current position (ASCII only).
    fn line(&self) -> Option<usize>;
    /// Reads all of the vertex element at once if the source can; `false`
    /// leaves it to the record-by-record path.
    fn fixed_vertices(
        &mut self,
        _el: &Element,
        _roles: &[Option<usize>],
        _mesh: &mut PlyMesh,
    ) -> bool {
        false
    }
}

struct BinarySource<'a, const BIG: bool> {
    data: &'a [u8],
    pos: usize,
}

/// Decodes the `ty` at the start of `bytes`, big-endian if `BIG`.
#[inline]
fn decode<const BIG: bool>(bytes: &[u8], ty: Scalar) -> Option<f64> {
    macro_rules! num {
        ($t:ty, $n:literal) => {{
            let b: [u8; $n] = bytes.get(..$n)?.try_into().ok()?;
            f64::from(if BIG {
                <$t>::from_be_bytes(b)
            } else {
                <$t>::from_le_bytes(b)
            })
        }};
    }
    Some(match ty {
        Scalar::I8 => num!(i8, 1),
        Scalar::U8 => num!(u8, 1),
        Scalar::I16 => num!(i16, 2),
        Scalar::U16 => num!(u16, 2),
        Scalar::I32 => num!(i32, 4),
        Scalar::U32 => num!(u32, 4),
        Scalar::F32 => num!(f32, 4),
        Scalar::F64 => num!(f64, 8),
    })
}

impl<const BIG: bool> Source for BinarySource<'_, BIG> {
    const BINARY: bool = true;

    #[inline]
    fn value(&mut self, ty: Scalar) -> Result<f64, ReadErr> {
        let value =
            decode::<BIG>(self.data.get(self.pos..).unwrap_or_default(), ty).ok_or(ReadErr::Eof)?;
        self.pos += ty.size();
        Ok(value)
    }

    fn fixed_vertices(
        &mut self,
        el: &Element,
        roles: &[Option<usize>],
        mesh: &mut PlyMesh,
    ) -> bool {
        // The usual layout, all scalars: decode just the wanted fields at
        // fixed offsets instead of walking every property through `value`.
        let (mut fields, mut stride) = (Vec::new(), 0);
        for (prop, role) in el.props.iter().zip(roles) {
            let Kind::Scalar(ty) = prop.kind else {
                return false;
            };
            if let Some(slot) = *role {
                fields.push((stride, ty, slot));
            }
            stride += ty.size();
        }
        let data = self.data;
        let end = el
            .count
            .checked_mul(stride)
            .and_then(|n| n.checked_add(self.pos));
        let Some(block) = end
            .and_then(|end| data.get(self.pos..end))
            .filter(|_| stride > 0)
        else {
            return false; // the record-by-record path reports the truncation
        };
        for record in block.chunks_exact(stride) {
            let mut rec = [0.0f32; 8];
            for &(offset, ty, slot) in &fields {
                let value = record
                    .get(offset..)
                    .and_then(|bytes| decode::<BIG>(bytes, ty));
                if let (Some(value), Some(out)) = (value, rec.get_mut(slot)) {
                    *out = value as f32;
                }
            }
            push_vertex(mesh, rec);
        }
        self.pos += block.len();
        true
    }

    fn skip(&mut self, n: u64, ty: Scalar) -> Result<(), ReadErr> {
        let bytes = n
            .checked_mul(ty.size() as u64)
            .and_then(|b| usize::try_from(b).ok())
            .ok_or(ReadErr::Eof)?;
        self.pos = self
            .pos
            .checked_add(bytes)
            .filter(|&end| end <= self.data.len())
            .ok_or(ReadErr::Eof)?;
        Ok(())
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn line(&self) -> Option<usize> {
        None
    }
}

/// An ASCII body is whitespace-separated tokens; like rply we do not insist
/// on one record per line, but we count lines for error messages.
struct AsciiSource<'a> {
    data: &'a [u8],
    pos: usize,
    /// Line of the byte at `pos`.
    line: usize,
    /// Line of the last token read ("end_header" before any).
    last_line: usize,
}

impl<'a> AsciiSource<'a> {
    fn token(&mut self) -> Option<&'a [u8]> {
        let rest = self.data.get(self.pos..)?;
        let start = rest.iter().position(|c| !c.is_ascii_whitespace())?;
        self.line += rest.iter().take(start).filter(|&&c| c == b'\n').count();
        let token = rest.get(start..)?;
        let len = token
            .iter()
            .position(u8::is_ascii_whitespace)
            .unwrap_or(token.len());
        self.pos += start + len;
        self.last_line = self.line;
        token.get(..len)
    }
}

impl Source for AsciiSource<'_> {
    const BINARY: bool = false;

    fn value(&mut self, ty: Scalar) -> Result<f64, ReadErr> {
        let token = self.token().ok_or(ReadErr::Eof)?;
        let parsed = std::str::from_utf8(token)
            .ok()
            .and_then(|text| ty.parse_text(text));
        parsed.ok_or_else(|| {
            // Cap the echo: a "token" may be a megabyte of binary junk.
            let shown = String::from_utf8_lossy(token).chars().take(40).collect();
            ReadErr::Bad(Box::new((self.last_line, shown, ty.info().0)))
        })
    }

    fn skip(&mut self, n: u64, ty: Scalar) -> Result<(), ReadErr> {
        // Parse rather than count, so bad tokens in ignored properties are
        // still reported; a huge n stops at the end of the data.
        for _ in 0..n {
            self.value(ty)?;
        }
        Ok(())
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn line(&self) -> Option<usize> {
        Some(self.last_line)
    }
}

/// Output slot of each vertex property: 0..3 position, 3..6 normal, 6..8 uv,
/// `None` for properties read and ignored.
struct VertexPlan {
    roles: Vec<Option<usize>>,
    normals: bool,
    uvs: bool,
}

fn vertex_plan(el: &Element) -> Result<VertexPlan, PlyError> {
    let find = |name: &str| {
        el.props
            .iter()
            .position(|p| p.name == name && matches!(p.kind, Kind::Scalar(_)))
    };
    let mut roles: Vec<Option<usize>> = vec![None; el.props.len()];
    let mut assign = |prop: usize, slot: usize| {
        if let Some(role) = roles.get_mut(prop) {
            *role = Some(slot);
        }
    };
    for (slot, axis) in ["x", "y", "z"].into_iter().enumerate() {
        assign(
            find(axis).ok_or(PlyError::MissingPosition {
                line: el.line,
                axis,
            })?,
            slot,
        );
    }
    let normals = match (find("nx"), find("ny"), find("nz")) {
        (Some(a), Some(b), Some(c)) => {
            assign(a, 3);
            assign(b, 4);
            assign(c, 5);
            true
        }
        _ => false,
    };
    let uv_names = [
        ("u", "v"),
        ("s", "t"),
        ("texture_u", "texture_v"),
        ("texture_s", "texture_t"),
    ];
    let uv = uv_names
        .into_iter()
        .find_map(|(a, b)| Some((find(a)?, find(b)?)));
    if let Some((a, b)) = uv {
        assign(a, 6);
        assign(b, 7);
    }
    Ok(VertexPlan {
        roles,
        normals,
        uvs: uv.is_some(),
    })
}

fn read_body<S: Source>(header: &Header, mut src: S) -> Result<PlyMesh, PlyError> {
    let Some((vertex_at, vertex)) = header
        .elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.name == "vertex")
    else {
        let message = "the header has no \"vertex\" element".to_string();
        return Err(PlyError::Header {
            line: header.end_line,
            message,
        });
    };
    let plan = vertex_plan(vertex)?;
    let face = header
        .elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.name == "face");
    let face_at = face.map(|(at, _)| at);
    let face_prop = face.and_then(|(_, el)| {
        el.props.iter().position(|p| {
            matches!(p.kind, Kind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        })
    });
    if let Some((_, el)) = face.filter(|(_, el)| el.count > 0 && face_prop.is_none()) {
        // pbrt refuses such files too: faces without indices are no mesh.
        let message = "element \"face\" has no \"vertex_indices\" list property".to_string();
        return Err(PlyError::Header {
            line: el.line,
            message,
        });
    }

    let mut mesh = PlyMesh {
        normals: plan.normals.then(Vec::new),
        uvs: plan.uvs.then(Vec::new),
        ..PlyMesh::default()
    };
    for (at, el) in header.elements.iter().enumerate() {
        // Records without properties occupy no bytes; skipping them here also
        // keeps a huge count from spinning an empty loop.
        if el.count == 0 || el.props.is_empty() {
            continue;
        }
        let cap = room_for(&src, el)?;
        if at == vertex_at {
            mesh.positions.reserve(cap);
            mesh.normals.iter_mut().for_each(|n| n.reserve(cap));
            mesh.uvs.iter_mut().for_each(|t| t.reserve(cap));
            if !src.fixed_vertices(el, &plan.roles, &mut mesh) {
                each_record(&mut src, el, |src| {
                    read_vertex(src, el, &plan.roles, &mut mesh)
                })?;
            }
        } else if let (true, Some(prop)) = (Some(at) == face_at, face_prop) {
            mesh.indices.reserve(cap.saturating_mul(3));
            let vertices = vertex.count;
            each_record(&mut src, el, |src| {
                read_face(src, el, prop, vertices, &mut mesh.indices, &mut mesh.quads)
            })?;
        } else {
            each_record(&mut src, el, |src| {
                el.props.iter().try_for_each(|prop| skip_prop(src, prop))
            })?;
        }
    }
    Ok(mesh)
}

/// How many records of `el` to reserve room for: the declared count, capped
/// by what the remaining bytes could hold so a lying header cannot make us
/// allocate gigabytes. A binary element of fixed-size records that cannot fit
/// is rejected here, naming the record where the data runs out.
fn room_for<S: Source>(src: &S, el: &Element) -> Result<usize, PlyError> {
    let room = src.remaining();
    if !S::BINARY {
        // At least one character and one separator per value.
        return Ok(el.count.min(room / (2 * el.props.len()).max(1)));
    }
    let (mut min, mut fixed) = (0usize, true);
    for prop in &el.props {
        match prop.kind {
            Kind::Scalar(ty) => min += ty.size(),
            Kind::List { len, .. } => {
                min += len.size();
                fixed = false;
            }
        }
    }
    if fixed && min > 0 && el.count.checked_mul(min).is_none_or(|need| need > room) {
        return Err(PlyError::Truncated {
            line: None,
            element: el.name.clone(),
            index: room / min,
            count: el.count,
        });
    }
    Ok(el.count.min(room / min.max(1)))
}

fn each_record<S: Source>(
    src: &mut S,
    el: &Element,
    mut record: impl FnMut(&mut S) -> Result<(), ReadErr>,
) -> Result<(), PlyError> {
    for index in 0..el.count {
        if let Err(err) = record(&mut *src) {
            return Err(body_err(err, src.line(), el, index));
        }
    }
    Ok(())
}

fn list_len<S: Source>(src: &mut S, len: Scalar, name: &str) -> Result<u64, ReadErr> {
    let value = src.value(len)?;
    if value < 0.0 {
        return Err(ReadErr::Invalid(
            format!("list \"{name}\" has negative length {value}").into(),
        ));
    }
    Ok(value as u64)
}

fn skip_prop<S: Source>(src: &mut S, prop: &Property) -> Result<(), ReadErr> {
    match prop.kind {
        Kind::Scalar(ty) => src.skip(1, ty),
        Kind::List { len, item } => {
            let n = list_len(src, len, &prop.name)?;
            src.skip(n, item)
        }
    }
}

fn read_vertex<S: Source>(
    src: &mut S,
    el: &Element,
    roles: &[Option<usize>],
    mesh: &mut PlyMesh,
) -> Result<(), ReadErr> {
    let mut rec = [0.0f32; 8];
    for (prop, role) in el.props.iter().zip(roles) {
        match (prop.kind, role) {
            (Kind::Scalar(ty), Some(slot)) => {
                let value = src.value(ty)?;
                if let Some(out) = rec.get_mut(*slot) {
                    *out = value as f32;
                }
            }
            _ => skip_prop(src, prop)?,
        }
    }
    push_vertex(mesh, rec);
    Ok(())
}

fn push_vertex(mesh: &mut PlyMesh, [x, y, z, nx, ny, nz, u, v]: [f32; 8]) {
    mesh.positions.push([x, y, z]);
    mesh.normals.iter_mut().for_each(|n| n.push([nx, ny, nz]));
    mesh.uvs.iter_mut().for_each(|t| t.push([u, v]));
}

fn vertex_index(value: f64, vertices: usize) -> Result<u32, ReadErr> {
    // The cast saturates (NaN gives 0), so the round trip fails exactly for
    // non-integers; it is also much cheaper than fract() in this hot loop.
    let index = value as i64;
    if index as f64 != value {
        return Err(ReadErr::Invalid(
            format!("vertex index {value} is not an integer").into(),
        ));
    }
    u32::try_from(index)
        .ok()
        .filter(|&i| (i as usize) < vertices)
        .ok_or(ReadErr::OutOfRange {
            vertex: index,
            vertices,
        })
}

fn read_face<S: Source>(
    src: &mut S,
    el: &Element,
    index_prop: usize,
    vertices: usize,
    indices: &mut Vec<u32>,
    quads: &mut Vec<u32>,
) -> Result<(), ReadErr> {
    for (at, prop) in el.props.iter().enumerate() {
        match prop.kind {
            Kind::List { len, item } if at == index_prop => {
                let n = list_len(src, len, &prop.name)?;
                if n < 3 {
                    return Err(ReadErr::TooFew(n));
                }
                // Fail before emitting triangles for a length the data cannot hold.
                if S::BINARY && n.saturating_mul(item.size() as u64) > src.remaining() as u64 {
                    return Err(ReadErr::Eof);
                }
                if n == 4 {
                    let mut q = [0u32; 4];
                    for v in &mut q {
                        *v = vertex_index(src.value(item)?, vertices)?;
                    }
                    quads.extend_from_slice(&[q[0], q[1], q[3], q[2]]);
                    continue;
                }
                // Fan around the first vertex as the indices stream past.
                let (mut first, mut prev) = (0, 0);
                for k in 0..n {
                    let index = vertex_index(src.value(item)?, vertices)?;
                    match k {
                        0 => first = index,
                        1 => {}
                        _ => indices.extend_from_slice(&[first, prev, index]),
                    }
                    prev = index;
                }
            }
            _ => skip_prop(src, prop)?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
