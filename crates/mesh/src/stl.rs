//! STL files, binary and ASCII, read with the `stl_io` crate.
//!
//! `stl_io` picks ASCII when a file starts with `solid ` and binary otherwise. Two common
//! kinds of real files trip that rule, so the bytes are classified here first:
//! - binary files whose free-text header starts with "solid" (many CAD exporters write
//!   that): a file whose size is exactly 84 + 50 · (its triangle count) is binary;
//! - ASCII files whose first line is a bare `solid` without a name.

use std::io::Cursor;

use stl_io::TriangleIterator;

use super::{MeshError, TriangleMesh, Units};

const HEADER: usize = 84;
const RECORD: usize = 50;

/// Reads an STL file given as bytes (any bytes: garbage gives an error, never a panic).
/// Coordinates are in `units`; the mesh is returned in millimetres, vertices shared by
/// exact coordinates, not yet checked for soundness ([`TriangleMesh::check`]).
pub fn read_stl(bytes: &[u8], units: Units) -> Result<TriangleMesh, MeshError> {
    let triangles = match classify(bytes)? {
        Kind::Binary => read_binary(bytes)?,
        Kind::Ascii(text) => read_ascii(text)?,
    };
    let scale = units.to_mm();
    let soup: Vec<[[f64; 3]; 3]> = triangles
        .iter()
        .map(|t| t.vertices.map(|v| v.0.map(|c| c as f64 * scale)))
        .collect();
    TriangleMesh::from_soup(&soup)
}

enum Kind {
    Binary,
    /// ASCII text, normalized so that `stl_io` accepts its first line.
    Ascii(Vec<u8>),
}

fn classify(bytes: &[u8]) -> Result<Kind, MeshError> {
    let binary_size = (bytes.len() >= HEADER).then(|| {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
        (count, HEADER as u64 + RECORD as u64 * count as u64)
    });
    if let Some((_, size)) = binary_size {
        if size == bytes.len() as u64 {
            return Ok(Kind::Binary);
        }
    }
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let start = text
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(text.len());
    let text = &text[start..];
    if let Some(rest) = text.strip_prefix(b"solid") {
        if rest.is_empty() || rest[0].is_ascii_whitespace() {
            // stl_io wants "solid " with a space even when the solid has no name.
            let mut normalized = b"solid ".to_vec();
            normalized.extend_from_slice(rest);
            return Ok(Kind::Ascii(normalized));
        }
    }
    Err(MeshError::NotStl(match binary_size {
        None => format!(
            "{} bytes, too short for a binary STL (84-byte header) and not ASCII STL (does not start with 'solid')",
            bytes.len()
        ),
        Some((count, size)) => format!(
            "not ASCII STL (does not start with 'solid') and not binary STL: its header announces {count} triangles, \
             which take {size} bytes, but the file has {} bytes",
            bytes.len()
        ),
    }))
}

fn read_binary(bytes: &[u8]) -> Result<Vec<stl_io::Triangle>, MeshError> {
    // The header is free text; make sure stl_io does not take it for ASCII.
    let mut data = bytes.to_vec();
    data[0] = b'#';
    let mut cursor = Cursor::new(data);
    let reader = stl_io::create_stl_reader(&mut cursor)
        .map_err(|e| MeshError::NotStl(format!("binary STL: {e}")))?;
    collect(reader, "binary STL")
}

fn read_ascii(text: Vec<u8>) -> Result<Vec<stl_io::Triangle>, MeshError> {
    let mut cursor = Cursor::new(text);
    let reader = stl_io::create_stl_reader(&mut cursor)
        .map_err(|e| MeshError::NotStl(format!("ASCII STL: {e}")))?;
    collect(reader, "ASCII STL")
}

fn collect(
    reader: Box<dyn TriangleIterator<Item = std::io::Result<stl_io::Triangle>> + '_>,
    what: &str,
) -> Result<Vec<stl_io::Triangle>, MeshError> {
    let mut out = Vec::new();
    for t in reader {
        let t = t.map_err(|e| {
            MeshError::NotStl(format!(
                "{what}: facet {}: {}",
                out.len() + 1,
                e.to_string().replace('\n', " ")
            ))
        })?;
        out.push(t);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: &str = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";

    fn binary(header: &[u8], triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut out = vec![b' '; 80];
        out[..header.len()].copy_from_slice(header);
        out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
        for t in triangles {
            out.extend_from_slice(&[0u8; 12]);
            for v in t {
                for c in v {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            out.extend_from_slice(&[0, 0]);
        }
        out
    }

    #[test]
    fn ascii_with_and_without_a_name() {
        for head in ["solid cube\n", "solid\n", "  solid\r\n"] {
            let m = read_stl(format!("{head}{TRI}endsolid\n").as_bytes(), Units::Mm).unwrap();
            assert_eq!((m.vertices.len(), m.triangles.len()), (3, 1), "{head:?}");
        }
    }

    #[test]
    fn binary_even_when_its_header_says_solid() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        for header in [&b"binary"[..], b"solid exported by CAD"] {
            let m = read_stl(&binary(header, &[t]), Units::M).unwrap();
            assert_eq!(m.vertices[1], [1000.0, 0.0, 0.0]);
        }
    }

    #[test]
    fn garbage_is_named() {
        let e = read_stl(b"hello", Units::Mm).unwrap_err().to_string();
        assert!(e.contains("too short for a binary STL"), "{e}");
        let e = read_stl(&[7u8; 200], Units::Mm).unwrap_err().to_string();
        assert!(e.contains("header announces 117901063 triangles"), "{e}");
        let e = read_stl(
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n",
            Units::Mm,
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("not an STL file: ASCII STL: facet 1:"), "{e}");
        let e = read_stl(format!("solid x\n{TRI}").as_bytes(), Units::Mm)
            .unwrap_err()
            .to_string();
        assert!(e.contains("facet 2") && e.contains("EOF"), "{e}");
        let mut truncated = binary(b"", &[[[0.0; 3]; 3]; 2]);
        truncated.truncate(100);
        let e = read_stl(&truncated, Units::Mm).unwrap_err().to_string();
        assert!(
            e.contains("announces 2 triangles, which take 184 bytes"),
            "{e}"
        );
    }

    #[test]
    fn non_finite_vertices_are_named() {
        let t = [[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let e = read_stl(&binary(b"", &[t]), Units::Mm)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "triangle 1: vertex (NaN, 0, 0) has a non-finite coordinate"
        );
    }
}
