//! VTK XML `.vtu` unstructured grids (read and write) and `.pvd` collections (write).
//!
//! In: the whole file. Reads one `Piece` with data arrays in `ascii`, inline
//! `binary` (base64, header and data encoded together or apart) or `appended`
//! (raw or base64) format, any VTK number type, either byte order, UInt32 or
//! UInt64 headers; compressed data is an "unsupported" error. Out: a
//! [`TetMesh`] built as for legacy VTK (cell type 10 kept, regions from cell
//! data `region` / `gmsh:physical` / `CellEntityIds`). Writes version 1.0,
//! little-endian, UInt64 headers, inline base64: Float64 points, Int64
//! connectivity and offsets, UInt8 types, UInt32 `region`, Float64 fields.
//! Stays true: what we write reads back to the same bits; no input panics.

use std::fmt::Write as _;
use std::path::Path;

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;
use quick_xml::events::{BytesStart, Event};

use super::cursor::{Cursor, Endian, array, shown};
use super::error::{MeshFileError, MeshFileErrorKind as K};
use super::tets::Place;
use super::vtk::{Cells, REGION_NAMES, assemble};
use super::{Field, FieldData};
use crate::mesh::TetMesh;

/// One `<DataArray>` as found in the XML.
#[derive(Debug, Default)]
struct ArrayDesc {
    section: Vec<u8>,
    name: Vec<u8>,
    ty: Vec<u8>,
    format: Vec<u8>,
    components: usize,
    offset: Option<usize>,
    text: Vec<u8>,
    line: usize,
}

fn line_at(data: &[u8], pos: u64) -> usize {
    let end = (pos as usize).min(data.len());
    1 + data[..end].iter().filter(|&&b| b == b'\n').count()
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn attr(e: &BytesStart<'_>, key: &[u8]) -> Option<Vec<u8>> {
    e.attributes().flatten().find(|a| a.key.as_ref().as_bytes() == key).map(|a| a.value.as_bytes().to_vec())
}

fn type_size(ty: &[u8]) -> Option<usize> {
    Some(match ty {
        b"Int8" | b"UInt8" => 1,
        b"Int16" | b"UInt16" => 2,
        b"Int32" | b"UInt32" | b"Float32" => 4,
        b"Int64" | b"UInt64" | b"Float64" => 8,
        _ => return None,
    })
}

fn decode_number(ty: &[u8], endian: Endian, b: &[u8]) -> f64 {
    match ty {
        b"Int8" => b[0] as i8 as f64,
        b"UInt8" => b[0] as f64,
        b"Int16" => endian.u16(array(b, 0)) as i16 as f64,
        b"UInt16" => endian.u16(array(b, 0)) as f64,
        b"Int32" => endian.u32(array(b, 0)) as i32 as f64,
        b"UInt32" => endian.u32(array(b, 0)) as f64,
        b"Float32" => endian.f32(array(b, 0)) as f64,
        b"Int64" => endian.u64(array(b, 0)) as i64 as f64,
        b"UInt64" => endian.u64(array(b, 0)) as f64,
        _ => endian.f64(array(b, 0)),
    }
}

/// Decodes a base64 block "header + data" where header and data may have been
/// encoded together (one stream) or apart (two padded streams).
fn decode_base64_block(text: &[u8], header_bytes: usize, endian: Endian) -> Result<Vec<u8>, String> {
    let chars: Vec<u8> = text.iter().copied().filter(|b| !b.is_ascii_whitespace()).collect();
    let header_chars = header_bytes.div_ceil(3) * 4;
    let head = chars.get(..header_chars).ok_or("base64 block shorter than its header")?;
    let head = STANDARD.decode(head).map_err(|e| format!("base64 header: {e}"))?;
    if head.len() < header_bytes {
        return Err("base64 header too short".into());
    }
    let nbytes = if header_bytes == 4 { endian.u32(array(&head, 0)) as u64 } else { endian.u64(array(&head, 0)) };
    let nbytes = usize::try_from(nbytes).map_err(|_| "base64 block length overflows")?;
    let total = nbytes.checked_add(header_bytes).ok_or("base64 block length overflows")?;
    let together_chars = total.div_ceil(3).saturating_mul(4);
    if let Some(t) = chars.get(..together_chars) {
        if let Ok(all) = STANDARD.decode(t) {
            if all.len() >= total {
                return Ok(all[header_bytes..total].to_vec());
            }
        }
    }
    let data_chars = nbytes.div_ceil(3).saturating_mul(4);
    let data = chars
        .get(header_chars..header_chars.saturating_add(data_chars))
        .ok_or_else(|| format!("base64 block shorter than the {nbytes} bytes its header announces"))?;
    let mut data = STANDARD.decode(data).map_err(|e| format!("base64 data: {e}"))?;
    if data.len() < nbytes {
        return Err("base64 data shorter than its header".into());
    }
    data.truncate(nbytes);
    Ok(data)
}

struct Layout<'a> {
    endian: Endian,
    header_bytes: usize,
    appended: Option<(&'a [u8], bool)>,
}

fn decode_array(path: &Path, a: &ArrayDesc, layout: &Layout<'_>) -> Result<Vec<f64>, MeshFileError> {
    let err = |kind| MeshFileError::at_line(path, a.line, kind);
    let size = type_size(&a.ty).ok_or_else(|| err(K::Unsupported(format!("DataArray type \"{}\"", shown(&a.ty)))))?;
    let bytes = match a.format.as_slice() {
        b"ascii" => {
            let mut c = Cursor::new(path, &a.text);
            c.line = a.line;
            let mut out = Vec::with_capacity(a.text.len() / 2);
            while let Some((tok, line)) = c.token() {
                let v = super::cursor::parse_float(tok).ok_or_else(|| {
                    c.err_at(line, K::BadNumber { token: shown(tok), what: format!("DataArray \"{}\"", shown(&a.name)) })
                })?;
                out.push(v);
            }
            return Ok(out);
        }
        b"binary" => decode_base64_block(&a.text, layout.header_bytes, layout.endian).map_err(|m| err(K::Invalid(m)))?,
        b"appended" => {
            let (data, raw) = layout.appended.ok_or_else(|| err(K::Invalid("appended DataArray but no <AppendedData>".into())))?;
            let offset = a.offset.ok_or_else(|| err(K::Invalid("appended DataArray without offset".into())))?;
            let block = data.get(offset..).ok_or_else(|| err(K::UnexpectedEof { expected: "appended data at the array's offset".into() }))?;
            if raw {
                let h = layout.header_bytes;
                let head = block.get(..h).ok_or_else(|| err(K::UnexpectedEof { expected: "an appended block header".into() }))?;
                let n = if h == 4 { layout.endian.u32(array(head, 0)) as u64 } else { layout.endian.u64(array(head, 0)) };
                let n = usize::try_from(n).unwrap_or(usize::MAX);
                block
                    .get(h..h.saturating_add(n))
                    .ok_or_else(|| err(K::UnexpectedEof { expected: format!("{n} bytes of appended data") }))?
                    .to_vec()
            } else {
                decode_base64_block(block, layout.header_bytes, layout.endian).map_err(|m| err(K::Invalid(m)))?
            }
        }
        other => return Err(err(K::Unsupported(format!("DataArray format \"{}\"", shown(other))))),
    };
    if bytes.len() % size != 0 {
        return Err(err(K::Invalid(format!("{} data bytes is not a whole number of {}", bytes.len(), shown(&a.ty)))));
    }
    Ok(bytes.chunks_exact(size).map(|b| decode_number(&a.ty, layout.endian, b)).collect())
}

/// Parses a `.vtu` file held in memory; `path` is only used in messages.
pub fn parse(path: &Path, data: &[u8]) -> Result<TetMesh, MeshFileError> {
    parse_with_fields(path, data).map(|(mesh, _)| mesh)
}

/// Parses a `.vtu` file and also returns its point and cell data arrays of 1
/// or 3 components (other arrays and the region array are left out). Cell
/// fields are kept only when every cell is a tetrahedron (so they align with
/// the mesh's tets); their lengths are checked like the writer's.
pub fn parse_with_fields(path: &Path, data: &[u8]) -> Result<(TetMesh, FieldData), MeshFileError> {
    let (xml, appended) = split_appended(path, data)?;
    let mut layout = Layout { endian: Endian::Little, header_bytes: 4, appended };
    let arrays = read_arrays(path, xml, &mut layout)?;
    let find_array = |section: &[u8], name: Option<&[u8]>| {
        arrays.iter().find(|a| a.section == section && name.is_none_or(|n| a.name == n))
    };
    let missing = |what: &str| MeshFileError::new(path, K::UnexpectedEof { expected: what.into() });
    let points = find_array(b"Points", None).ok_or_else(|| missing("a Points DataArray"))?;
    let conn = find_array(b"Cells", Some(b"connectivity")).ok_or_else(|| missing("a connectivity DataArray"))?;
    let offs = find_array(b"Cells", Some(b"offsets")).ok_or_else(|| missing("an offsets DataArray"))?;
    let types = find_array(b"Cells", Some(b"types")).ok_or_else(|| missing("a types DataArray"))?;
    let region = REGION_NAMES.iter().find_map(|r| find_array(b"CellData", Some(r.as_bytes())));

    let point_values = decode_array(path, points, &layout)?;
    let conn_values = decode_array(path, conn, &layout)?;
    let mut offsets = vec![0.0];
    offsets.extend(decode_array(path, offs, &layout)?);
    let type_values = decode_array(path, types, &layout)?;
    let region_values = region.map(|r| decode_array(path, r, &layout)).transpose()?;
    let point_places = vec![Place::line(points.line); point_values.len()];
    let cells = Cells {
        offsets: &offsets,
        connectivity: &conn_values,
        places: &[],
        types: &type_values,
        types_place: Place::line(conn.line),
    };
    let regions = region.zip(region_values.as_deref()).map(|(r, v)| (v, Place::line(r.line)));
    let mesh = assemble(path, &point_values, &point_places, &cells, regions)?;
    let all_tets = type_values.iter().all(|&t| t == 10.0);
    let fields = read_fields(path, &arrays, &layout, &mesh, all_tets)?;
    Ok((mesh, fields))
}

/// The XML part of the file and its appended raw data (from after the `_` that starts it; whether it is `raw`
/// rather than base64), if any: appended raw data is not XML, so it is cut off before parsing.
fn split_appended<'a>(path: &Path, data: &'a [u8]) -> Result<(&'a [u8], Option<(&'a [u8], bool)>), MeshFileError> {
    let Some(start) = find(data, b"<AppendedData") else {
        return Ok((data, None));
    };
    let tag_end = data[start..].iter().position(|&b| b == b'>').map(|k| start + k);
    let tag_end = tag_end.ok_or_else(|| MeshFileError::new(path, K::UnexpectedEof { expected: "the end of <AppendedData>".into() }))?;
    let tag = &data[start..tag_end];
    let raw = find(tag, b"raw").is_some();
    let underscore = data[tag_end..].iter().position(|&b| b == b'_').map(|k| tag_end + k + 1);
    let underscore =
        underscore.ok_or_else(|| MeshFileError::new(path, K::UnexpectedEof { expected: "the '_' that starts appended data".into() }))?;
    Ok((&data[..start], Some((&data[underscore..], raw))))
}

/// Every DataArray of the XML with its section and text; the VTKFile element's byte order and header size go
/// into `layout`. One Piece, uncompressed.
fn read_arrays(path: &Path, xml: &[u8], layout: &mut Layout<'_>) -> Result<Vec<ArrayDesc>, MeshFileError> {
    let mut reader = quick_xml::Reader::from_reader(xml);
    let mut stack: Vec<Vec<u8>> = Vec::new();
    let mut arrays: Vec<ArrayDesc> = Vec::new();
    let mut current: Option<ArrayDesc> = None;
    let mut pieces = 0usize;
    let mut seen_file = false;
    loop {
        let event = reader.read_event().map_err(|e| {
            MeshFileError::at_line(path, line_at(xml, reader.error_position()), K::Xml(e.to_string()))
        })?;
        let here = || line_at(xml, reader.buffer_position());
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(event, Event::Empty(_));
                let name = e.name().as_ref().as_bytes().to_vec();
                match name.as_slice() {
                    b"VTKFile" => {
                        seen_file = true;
                        file_attributes(e, layout).map_err(|kind| MeshFileError::at_line(path, here(), kind))?;
                    }
                    b"Piece" => {
                        pieces += 1;
                        if pieces > 1 {
                            return Err(MeshFileError::at_line(path, here(), K::Unsupported("more than one Piece".into())));
                        }
                    }
                    b"DataArray" => {
                        let desc = array_desc(e, stack.last().cloned().unwrap_or_default(), here());
                        if empty {
                            arrays.push(desc);
                        } else {
                            current = Some(desc);
                        }
                    }
                    _ => {}
                }
                if !empty {
                    stack.push(name);
                }
            }
            Event::Text(t) => {
                if let Some(a) = current.as_mut() {
                    a.text.extend_from_slice(t.as_bytes());
                }
            }
            Event::End(e) => {
                if e.name().as_ref() == "DataArray" {
                    if let Some(a) = current.take() {
                        arrays.push(a);
                    }
                }
                stack.pop();
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if !seen_file {
        return Err(MeshFileError::new(path, K::Expected { expected: "a <VTKFile> element".into(), found: shown(&xml[..xml.len().min(40)]) }));
    }
    Ok(arrays)
}

/// The VTKFile element: an UnstructuredGrid, uncompressed; its byte order and header size into `layout`.
fn file_attributes(e: &quick_xml::events::BytesStart<'_>, layout: &mut Layout<'_>) -> Result<(), K> {
    let ty = attr(e, b"type").unwrap_or_default();
    if ty != b"UnstructuredGrid" {
        return Err(K::Unsupported(format!("VTK XML type \"{}\" (only UnstructuredGrid)", shown(&ty))));
    }
    if attr(e, b"byte_order").as_deref() == Some(b"BigEndian") {
        layout.endian = Endian::Big;
    }
    if attr(e, b"header_type").as_deref() == Some(b"UInt64") {
        layout.header_bytes = 8;
    }
    if attr(e, b"compressor").is_some_and(|c| !c.is_empty()) {
        return Err(K::Unsupported("compressed VTU data (save without compression)".into()));
    }
    Ok(())
}

/// A DataArray element's description (its text still to come), in `section`, on `line`.
fn array_desc(e: &quick_xml::events::BytesStart<'_>, section: Vec<u8>, line: usize) -> ArrayDesc {
    ArrayDesc {
        section,
        name: attr(e, b"Name").unwrap_or_default(),
        ty: attr(e, b"type").unwrap_or_default(),
        format: attr(e, b"format").unwrap_or_else(|| b"ascii".to_vec()),
        components: attr(e, b"NumberOfComponents")
            .and_then(|c| super::cursor::parse_int(&c))
            .and_then(|c| usize::try_from(c).ok())
            .unwrap_or(1),
        offset: attr(e, b"offset").and_then(|o| super::cursor::parse_int(&o)).and_then(|o| usize::try_from(o).ok()),
        text: Vec::new(),
        line,
    }
}

/// The point and cell arrays of 1 or 3 components other than the region, checked against the mesh's counts (cell
/// arrays only when every cell is a tetrahedron).
fn read_fields(path: &Path, arrays: &[ArrayDesc], layout: &Layout<'_>, mesh: &TetMesh, all_tets: bool) -> Result<FieldData, MeshFileError> {
    let mut fields = FieldData::default();
    for a in arrays {
        let list = match a.section.as_slice() {
            b"PointData" => &mut fields.point,
            b"CellData" if all_tets => &mut fields.cell,
            _ => continue,
        };
        if a.components != 1 && a.components != 3 || REGION_NAMES.iter().any(|r| r.as_bytes() == a.name) {
            continue;
        }
        let v = decode_array(path, a, layout)?;
        let ragged = v.len() % a.components != 0;
        let field = if a.components == 1 {
            Field::Scalar(v)
        } else {
            Field::Vector(v.chunks_exact(3).map(|c| crate::math::Vec3::new(c[0], c[1], c[2])).collect())
        };
        let expected = if a.section == b"PointData" { mesh.positions.len() } else { mesh.tets.len() };
        if field.len() != expected || ragged {
            let of = if a.section == b"PointData" { "nodes" } else { "tetrahedra" };
            let name = String::from_utf8_lossy(&a.name).into_owned();
            return Err(MeshFileError::at_line(path, a.line, K::FieldLength { name, expected, found: field.len(), of }));
        }
        list.push((String::from_utf8_lossy(&a.name).into_owned(), field));
    }
    Ok(fields)
}

fn data_array(s: &mut String, ty: &str, name: Option<&str>, components: usize, bytes: &[u8]) {
    let mut block = Vec::with_capacity(8 + bytes.len());
    block.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    block.extend_from_slice(bytes);
    let _ = write!(s, "        <DataArray type=\"{ty}\"");
    if let Some(n) = name {
        let _ = write!(s, " Name=\"{n}\"");
    }
    if components != 1 {
        let _ = write!(s, " NumberOfComponents=\"{components}\"");
    }
    s.push_str(" format=\"binary\">\n          ");
    STANDARD.encode_string(&block, s);
    s.push_str("\n        </DataArray>\n");
}

fn field_bytes(field: &Field) -> (Vec<u8>, usize) {
    match field {
        Field::Scalar(v) => (v.iter().flat_map(|x| x.to_le_bytes()).collect(), 1),
        Field::Vector(v) => (v.iter().flat_map(|p| [p.x, p.y, p.z]).flat_map(|x| x.to_le_bytes()).collect(), 3),
    }
}

/// Writes the mesh and fields as a VTK XML UnstructuredGrid (see the module doc).
pub fn write(mesh: &TetMesh, fields: &FieldData) -> String {
    let n = mesh.positions.len();
    let m = mesh.tets.len();
    let mut s = String::with_capacity(64 + 40 * n + 60 * m);
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <UnstructuredGrid>\n");
    let _ = writeln!(s, "    <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{m}\">");
    s.push_str("      <PointData>\n");
    for (name, f) in &fields.point {
        let (b, k) = field_bytes(f);
        data_array(&mut s, "Float64", Some(name), k, &b);
    }
    s.push_str("      </PointData>\n      <CellData>\n");
    let regions: Vec<u8> = mesh.regions.iter().flat_map(|r| r.to_le_bytes()).collect();
    data_array(&mut s, "UInt32", Some("region"), 1, &regions);
    for (name, f) in &fields.cell {
        let (b, k) = field_bytes(f);
        data_array(&mut s, "Float64", Some(name), k, &b);
    }
    s.push_str("      </CellData>\n      <Points>\n");
    let points: Vec<u8> = mesh.positions.iter().flat_map(|p| [p.x, p.y, p.z]).flat_map(|x| x.to_le_bytes()).collect();
    data_array(&mut s, "Float64", Some("Points"), 3, &points);
    s.push_str("      </Points>\n      <Cells>\n");
    let conn: Vec<u8> = mesh.tets.iter().flatten().flat_map(|&k| (k as i64).to_le_bytes()).collect();
    data_array(&mut s, "Int64", Some("connectivity"), 1, &conn);
    let offsets: Vec<u8> = (1..=m as i64).flat_map(|k| (4 * k).to_le_bytes()).collect();
    data_array(&mut s, "Int64", Some("offsets"), 1, &offsets);
    data_array(&mut s, "UInt8", Some("types"), 1, &vec![10u8; m]);
    s.push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    s
}

/// Escapes text for an XML attribute value.
fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// The text of a `.pvd` collection: (time in s, file relative to the `.pvd`).
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<String, MeshFileError> {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for (i, (time, file)) in entries.iter().enumerate() {
        if !time.is_finite() {
            return Err(MeshFileError::new(path, K::Invalid(format!("time step {i} has time {time}"))));
        }
        let _ = writeln!(s, "    <DataSet timestep=\"{time:?}\" group=\"\" part=\"0\" file=\"{}\"/>", xml_escape(file));
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_blocks_decode_whether_encoded_together_or_apart() {
        let data = [1u8, 2, 3, 4, 5, 6, 7];
        let mut together = (data.len() as u32).to_le_bytes().to_vec();
        together.extend_from_slice(&data);
        let one = STANDARD.encode(&together);
        let two = format!("{}{}", STANDARD.encode((data.len() as u32).to_le_bytes()), STANDARD.encode(data));
        for text in [one, two] {
            let got = decode_base64_block(text.as_bytes(), 4, Endian::Little).expect("valid block");
            assert_eq!(got, data, "block {text}");
        }
        assert!(decode_base64_block(b"AAAA", 4, Endian::Little).is_err(), "short header");
    }

    #[test]
    fn sixteen_bit_numbers_decode_in_both_byte_orders() {
        assert_eq!(decode_number(b"Int16", Endian::Little, &(-3i16).to_le_bytes()), -3.0);
        assert_eq!(decode_number(b"UInt16", Endian::Big, &(513u16).to_be_bytes()), 513.0);
    }

    #[test]
    fn pvd_escapes_names_and_rejects_nan_time() {
        let s = write_pvd(Path::new("a.pvd"), &[(0.5, "a&b.vtu".into())]).expect("finite time");
        assert!(s.contains("timestep=\"0.5\"") && s.contains("file=\"a&amp;b.vtu\""), "{s}");
        assert!(write_pvd(Path::new("a.pvd"), &[(f64::NAN, "x.vtu".into())]).is_err());
    }
}
