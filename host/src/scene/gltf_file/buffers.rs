//! A glTF file's bytes: URIs (files and data URIs, percent-decoded), node matrices read in f64
//! from the JSON, and accessors read and bounds-checked before anything is allocated.
#[allow(unused_imports)]
use super::*;

/// Reads a buffer or image URI: a base64 data URI, or a file relative to the glTF file.
pub(super) fn read_uri(path: &Path, uri: &str, files: &dyn Files, what: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((header, data)) = rest.split_once(',') else {
            bail!("{}: {what}: malformed data URI (no comma)", path.display());
        };
        if !header.ends_with(";base64") {
            bail!("{}: {what}: data URI is not base64", path.display());
        }
        return base64::engine::general_purpose::STANDARD
            .decode(data.trim())
            .map_err(|e| anyhow!("{}: {what}: bad base64 in data URI: {e}", path.display()));
    }
    let name = percent_decode(uri);
    let full = path.parent().unwrap_or(Path::new("")).join(&name);
    files.read(&full).map_err(|e| anyhow!("{}: {what} {uri:?}: cannot read {}: {e}", path.display(), full.display()))
}

/// `%XX` escapes of a relative URI decoded (the file names glTF exporters write).
pub(super) fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let Some(v) = std::str::from_utf8(&b[i + 1..i + 3]).ok().and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The local transform of node `i` from the JSON, in f64 (matrix, or T·R·S).
pub(super) fn node_matrix(path: &Path, json: &serde_json::Value, i: usize) -> Result<DMat4> {
    let node = &json["nodes"][i];
    let numbers = |key: &str, n: usize| -> Result<Option<Vec<f64>>> {
        let Some(v) = node.get(key) else { return Ok(None) };
        let a = v
            .as_array()
            .filter(|a| a.len() == n)
            .ok_or_else(|| anyhow!("{}: node {i}: {key} needs {n} numbers", path.display()))?;
        let mut out = Vec::with_capacity(n);
        for x in a {
            match x.as_f64() {
                Some(x) if x.is_finite() && x.abs() <= MAX_COORDINATE as f64 => out.push(x),
                _ => {
                    bail!("{}: node {i}: {key}: {x} is not a finite number within ±{MAX_COORDINATE:e}", path.display())
                }
            }
        }
        Ok(Some(out))
    };
    if let Some(m) = numbers("matrix", 16)? {
        return Ok(DMat4::from_cols_slice(&m));
    }
    let t = numbers("translation", 3)?.map_or(DVec3::ZERO, |v| DVec3::new(v[0], v[1], v[2]));
    let s = numbers("scale", 3)?.map_or(DVec3::ONE, |v| DVec3::new(v[0], v[1], v[2]));
    let r = match numbers("rotation", 4)? {
        Some(q) => {
            let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
            if q.length() == 0.0 {
                bail!("{}: node {i}: rotation is the zero quaternion", path.display());
            }
            q.normalize()
        }
        None => DQuat::IDENTITY,
    };
    Ok(DMat4::from_scale_rotation_translation(s, r, t))
}

/// The most elements an accessor without a buffer view (all zeros, or sparse) may have.
pub(super) const MAX_ZERO_ELEMENTS: usize = 1 << 26;

/// An accessor's elements as f64, `components` per element (normalised integers scaled as the
/// specification says), after checking it against its buffer view and buffer.
pub(super) fn read_accessor(
    buffers: &[Vec<u8>],
    a: &::gltf::Accessor,
    components: usize,
    what: &str,
) -> std::result::Result<Vec<f64>, String> {
    use ::gltf::accessor::DataType;
    if a.dimensions().multiplicity() != components {
        return Err(format!(
            "{what}: accessor {} has {:?} elements, not {components} components",
            a.index(),
            a.dimensions()
        ));
    }
    let size = a.data_type().size();
    let elem = size * components;
    let count = a.count();
    let decode = |bytes: &[u8]| -> f64 {
        match a.data_type() {
            DataType::F32 => f32::from_le_bytes(bytes[..4].try_into().unwrap()) as f64,
            DataType::U32 => u32::from_le_bytes(bytes[..4].try_into().unwrap()) as f64,
            DataType::U16 => {
                let v = u16::from_le_bytes(bytes[..2].try_into().unwrap()) as f64;
                if a.normalized() {
                    v / 65535.0
                } else {
                    v
                }
            }
            DataType::U8 => {
                let v = bytes[0] as f64;
                if a.normalized() {
                    v / 255.0
                } else {
                    v
                }
            }
            DataType::I16 => {
                let v = i16::from_le_bytes(bytes[..2].try_into().unwrap()) as f64;
                if a.normalized() {
                    (v / 32767.0).max(-1.0)
                } else {
                    v
                }
            }
            DataType::I8 => {
                let v = bytes[0] as i8 as f64;
                if a.normalized() {
                    (v / 127.0).max(-1.0)
                } else {
                    v
                }
            }
        }
    };
    // The bytes of a view, checked against its buffer.
    let view_bytes = |view: &::gltf::buffer::View| -> std::result::Result<&[u8], String> {
        let buffer = buffers
            .get(view.buffer().index())
            .ok_or_else(|| format!("{what}: buffer {} missing", view.buffer().index()))?;
        let end = view.offset().checked_add(view.length()).filter(|&e| e <= buffer.len()).ok_or_else(|| {
            format!(
                "{what}: buffer view {} (bytes {}..+{}) lies outside buffer {} ({} bytes)",
                view.index(),
                view.offset(),
                view.length(),
                view.buffer().index(),
                buffer.len()
            )
        })?;
        Ok(&buffer[view.offset()..end])
    };
    // `n` elements of `elem` bytes starting at `offset` within `bytes` every `stride`.
    let elements =
        |bytes: &[u8], offset: usize, stride: usize, n: usize, elem: usize| -> std::result::Result<(), String> {
            if n == 0 {
                return Ok(());
            }
            let end = (n - 1).checked_mul(stride).and_then(|x| x.checked_add(offset)).and_then(|x| x.checked_add(elem));
            match end {
                Some(e) if e <= bytes.len() => Ok(()),
                _ => Err(format!(
                "{what}: accessor {} needs {n} elements of {elem} bytes every {stride} from byte {offset}, beyond its \
                 buffer view ({} bytes)",
                a.index(),
                bytes.len()
            )),
            }
        };
    // Checked before anything is allocated: a count the buffer cannot hold is an error.
    let base = match a.view() {
        Some(view) => {
            let bytes = view_bytes(&view)?;
            let stride = view.stride().unwrap_or(elem);
            if stride < elem {
                return Err(format!(
                    "{what}: accessor {}: byteStride {stride} is below its element size {elem}",
                    a.index()
                ));
            }
            elements(bytes, a.offset(), stride, count, elem)?;
            Some((bytes, stride))
        }
        None if count > MAX_ZERO_ELEMENTS => {
            return Err(format!(
                "{what}: accessor {} has no buffer view and {count} elements (at most {MAX_ZERO_ELEMENTS})",
                a.index()
            ))
        }
        None => None,
    };
    let mut out = vec![0.0; count.checked_mul(components).ok_or_else(|| format!("{what}: accessor count overflows"))?];
    if let Some((bytes, stride)) = base {
        for (i, e) in out.chunks_mut(components).enumerate() {
            let at = a.offset() + i * stride;
            for (c, x) in e.iter_mut().enumerate() {
                *x = decode(&bytes[at + c * size..]);
            }
        }
    }
    if let Some(sparse) = a.sparse() {
        let n = sparse.count();
        let (iv, vv) = (sparse.indices(), sparse.values());
        let ib = view_bytes(&iv.view())?;
        let isize = iv.index_type().size();
        elements(ib, iv.offset(), isize, n, isize)?;
        let vb = view_bytes(&vv.view())?;
        elements(vb, vv.offset(), elem, n, elem)?;
        for k in 0..n {
            let at = iv.offset() + k * isize;
            let i = match isize {
                1 => ib[at] as usize,
                2 => u16::from_le_bytes([ib[at], ib[at + 1]]) as usize,
                _ => u32::from_le_bytes(ib[at..at + 4].try_into().unwrap()) as usize,
            };
            if i >= count {
                return Err(format!("{what}: accessor {}: sparse index {i} beyond its {count} elements", a.index()));
            }
            for c in 0..components {
                out[i * components + c] = decode(&vb[vv.offset() + k * elem + c * size..]);
            }
        }
    }
    if out.iter().any(|x| !x.is_finite()) {
        return Err(format!("{what}: accessor {} holds a value that is not finite", a.index()));
    }
    Ok(out)
}
