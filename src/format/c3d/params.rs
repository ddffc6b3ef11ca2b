//! The C3D parameter section: groups and parameters (spec/c3d.md §1
//! "Parameter section"). A pure decoder and encoder over bytes.

use super::processor::Processor;
use super::FormatError;

/// Element type of a parameter, from its type byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamType {
    /// −1: characters.
    Char,
    /// 1: bytes (ezc3d writes POINT:USED this way).
    Byte,
    /// 2: 16-bit integers.
    Int16,
    /// 4: floats in the processor's format.
    Float,
}

impl ParamType {
    fn from_code(code: i8) -> Option<ParamType> {
        match code {
            -1 => Some(ParamType::Char),
            1 => Some(ParamType::Byte),
            2 => Some(ParamType::Int16),
            4 => Some(ParamType::Float),
            _ => None,
        }
    }

    fn code(self) -> i8 {
        match self {
            ParamType::Char => -1,
            ParamType::Byte => 1,
            ParamType::Int16 => 2,
            ParamType::Float => 4,
        }
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        self.code().unsigned_abs() as usize
    }
}

/// One parameter with its raw data, kept raw so each reader can interpret
/// it the way the field needs (a count, a float, labels).
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    /// Group name, upper case ("POINT").
    pub group: String,
    /// Parameter name, upper case ("LABELS2").
    pub name: String,
    /// Element type, which decides how `data` is read.
    pub kind: ParamType,
    /// Dimensions as stored (first varies fastest); empty for a scalar.
    pub dims: Vec<usize>,
    /// The raw elements, `dims` product × element size bytes.
    pub data: Vec<u8>,
    /// File offset of the parameter's record, for error messages.
    pub offset: u64,
    /// Byte order and float format of `data`.
    pub processor: Processor,
}

impl Param {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len() / self.kind.size()
    }

    /// True for a parameter that holds no element (a declared, unset value).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// "GROUP:NAME", as users and vendors write it.
    pub fn key(&self) -> String {
        format!("{}:{}", self.group, self.name)
    }

    /// Element `i` as a number, whatever the type: bytes and 16-bit words are
    /// unsigned (counts and frame numbers use the full 0–65535 range), floats
    /// as stored. None for characters or past the end.
    pub fn number(&self, i: usize) -> Option<f64> {
        let s = self.kind.size();
        let b = self.data.get(i * s..i * s + s)?;
        match self.kind {
            ParamType::Char => None,
            ParamType::Byte => Some(b[0] as f64),
            ParamType::Int16 => Some(self.processor.u16([b[0], b[1]]) as f64),
            ParamType::Float => Some(self.processor.f32([b[0], b[1], b[2], b[3]]) as f64),
        }
    }

    /// Element `i` as a signed 16-bit integer (only for Int16 parameters).
    pub fn i16(&self, i: usize) -> Option<i16> {
        if self.kind != ParamType::Int16 {
            return None;
        }
        let b = self.data.get(i * 2..i * 2 + 2)?;
        Some(self.processor.i16([b[0], b[1]]))
    }

    /// The first element as a non-negative whole count, whatever the type.
    pub fn count(&self) -> Option<u64> {
        let v = self.number(0)?;
        (0.0..4.0e9).contains(&v).then(|| v.round() as u64)
    }

    /// Character data as strings: one per column of a `[len, n]` array, one
    /// for `[len]` or a scalar; trailing spaces and NULs removed.
    pub fn strings(&self) -> Vec<String> {
        if self.kind != ParamType::Char {
            return Vec::new();
        }
        let len = self.dims.first().copied().unwrap_or(1).max(1);
        self.data
            .chunks(len)
            .map(|c| {
                String::from_utf8_lossy(c)
                    .trim_end_matches([' ', '\0'])
                    .trim_start()
                    .to_string()
            })
            .collect()
    }
}

/// All parameters of a file in file order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params {
    /// Parameters as they appear; lookups take the first match, as other
    /// readers do when a file repeats one.
    pub list: Vec<Param>,
}

impl Params {
    /// The first parameter `group:name` (case-insensitive).
    pub fn get(&self, group: &str, name: &str) -> Option<&Param> {
        self.list
            .iter()
            .find(|p| p.group.eq_ignore_ascii_case(group) && p.name.eq_ignore_ascii_case(name))
    }
}

fn take<'a>(
    sec: &'a [u8],
    at: usize,
    n: usize,
    base: u64,
    what: &str,
) -> Result<&'a [u8], FormatError> {
    sec.get(at..at.saturating_add(n))
        .ok_or_else(|| FormatError {
            at: base + at as u64,
            msg: format!("parameter section ends inside {what}"),
        })
}

/// Decodes the parameter section. `sec` starts at the section's first byte
/// (the 4-byte prefix) and `base` is its offset in the file. Parsing stops
/// at a record with name length 0 or group id 0, after a record whose
/// offset-to-next is 0, or at the end of `sec`; a record that points
/// backwards or past the end is an error, so a corrupt file cannot loop.
pub fn decode(sec: &[u8], base: u64, p: Processor) -> Result<Params, FormatError> {
    let mut groups: Vec<(u8, String)> = Vec::new();
    // Parameters with their group id; names are resolved at the end because
    // a group record may follow its parameters.
    let mut raw: Vec<(u8, Param)> = Vec::new();
    let mut pos = 4usize;
    while pos + 2 <= sec.len() {
        let name_len = sec[pos] as i8;
        let id = sec[pos + 1] as i8;
        if name_len == 0 || id == 0 {
            break;
        }
        let n = name_len.unsigned_abs() as usize;
        let name = record_name(sec, pos, n, base)?;
        let off_at = pos + 2 + n;
        let offset = record_offset(sec, off_at, base, &name, p)?;
        if id < 0 {
            groups.push((id.unsigned_abs(), name));
        } else {
            let param = decode_param(sec, pos, off_at + 2, base, name, p)?;
            raw.push((id.unsigned_abs(), param));
        }
        if offset == 0 {
            break;
        }
        let end = off_at + offset as usize;
        if end <= pos {
            return Err(FormatError {
                at: base + off_at as u64,
                msg: "parameter record points back to itself".into(),
            });
        }
        pos = end;
    }
    Ok(Params {
        list: name_groups(raw, &groups),
    })
}

/// The name of the record at `pos` (`n` bytes after its two leading bytes),
/// trimmed and upper-cased as lookups expect.
fn record_name(sec: &[u8], pos: usize, n: usize, base: u64) -> Result<String, FormatError> {
    let name_bytes = take(sec, pos + 2, n, base, "a parameter name")?;
    Ok(String::from_utf8_lossy(name_bytes)
        .trim()
        .to_ascii_uppercase())
}

/// The record's offset to the next record (at `off_at`, relative to it);
/// 0 ends the section, a negative one is an error so that a corrupt file
/// cannot loop.
fn record_offset(
    sec: &[u8],
    off_at: usize,
    base: u64,
    name: &str,
    p: Processor,
) -> Result<i16, FormatError> {
    // The name as messages quote it: a name is file content and may
    // hold newlines or escape codes.
    let shown = crate::error::excerpt(name);
    let ob = take(
        sec,
        off_at,
        2,
        base,
        &format!("the record offset of \"{shown}\""),
    )?;
    let offset = p.i16([ob[0], ob[1]]);
    if offset < 0 {
        return Err(FormatError {
            at: base + off_at as u64,
            msg: format!("parameter \"{shown}\": offset to the next record is negative ({offset})"),
        });
    }
    Ok(offset)
}

/// Decodes a parameter record's body (type, dimensions, data) starting at
/// `body`; `record` is where the record starts, kept for re-encoding.
fn decode_param(
    sec: &[u8],
    record: usize,
    body: usize,
    base: u64,
    name: String,
    p: Processor,
) -> Result<Param, FormatError> {
    let shown = crate::error::excerpt(&name);
    let kb = take(sec, body, 2, base, &format!("parameter \"{shown}\""))?;
    let kind = ParamType::from_code(kb[0] as i8).ok_or_else(|| FormatError {
        at: base + body as u64,
        msg: format!(
            "parameter \"{shown}\": type {} is not one of -1 (char), 1 (byte), 2 (int16), 4 (float)",
            kb[0] as i8
        ),
    })?;
    let ndims = kb[1] as usize;
    let dims: Vec<usize> = take(
        sec,
        body + 2,
        ndims,
        base,
        &format!("parameter \"{shown}\" dimensions"),
    )?
    .iter()
    .map(|&d| d as usize)
    .collect();
    // Each dimension is at most 255, but up to 255 of them could
    // overflow: the product is checked against the section instead.
    let mut elems: usize = 1;
    for &d in &dims {
        elems = elems.saturating_mul(d);
    }
    let bytes = elems.saturating_mul(kind.size());
    let data = take(
        sec,
        body + 2 + ndims,
        bytes,
        base,
        &format!("parameter \"{shown}\" data ({bytes} bytes)"),
    )?;
    Ok(Param {
        group: String::new(),
        name,
        kind,
        dims,
        data: data.to_vec(),
        offset: base + record as u64,
        processor: p,
    })
}

/// Gives each parameter its group's name once all group records are known
/// (`GROUPn` for a group id without a record).
fn name_groups(raw: Vec<(u8, Param)>, groups: &[(u8, String)]) -> Vec<Param> {
    raw.into_iter()
        .map(|(gid, mut param)| {
            param.group = groups
                .iter()
                .find(|(id, _)| *id == gid)
                .map(|(_, n)| n.clone())
                .unwrap_or_else(|| format!("GROUP{gid}"));
            param
        })
        .collect()
}

/// A parameter value to encode.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// 16-bit integers with their dimensions (empty = scalar).
    Int16(Vec<i16>, Vec<usize>),
    /// Bytes with their dimensions.
    Byte(Vec<u8>, Vec<usize>),
    /// Floats with their dimensions.
    Float(Vec<f32>, Vec<usize>),
    /// Strings padded with spaces to a common length (`[len, n]`), or one
    /// string (`[len]`) when `array` is false.
    Chars {
        /// The strings, in order.
        strings: Vec<String>,
        /// Written as a 2-D array (`[len, n]`) rather than one string.
        array: bool,
    },
}

/// Encodes a parameter section: `groups` are (id, name), `params` are
/// (group id, name, value). Returns the bytes padded to whole blocks, with
/// byte 2 = number of blocks and byte 3 = processor.
pub fn encode(groups: &[(u8, &str)], params: &[(u8, &str, Value)], p: Processor) -> Vec<u8> {
    let mut out = vec![0x01, 0x50, 0, p.code()];
    let mut records: Vec<Vec<u8>> = Vec::new();
    for &(id, name) in groups {
        let mut r = vec![name.len() as u8, (-(id as i8)) as u8];
        r.extend_from_slice(name.as_bytes());
        r.extend_from_slice(&[0, 0]); // offset, patched below
        r.push(0); // description length
        records.push(r);
    }
    for (id, name, value) in params {
        let mut r = vec![name.len() as u8, *id];
        r.extend_from_slice(name.as_bytes());
        r.extend_from_slice(&[0, 0]);
        let (code, dims, data): (i8, Vec<usize>, Vec<u8>) = match value {
            Value::Int16(v, d) => (2, d.clone(), v.iter().flat_map(|&x| p.put_i16(x)).collect()),
            Value::Byte(v, d) => (1, d.clone(), v.clone()),
            Value::Float(v, d) => (4, d.clone(), v.iter().flat_map(|&x| p.put_f32(x)).collect()),
            Value::Chars { strings, array } => {
                let len = strings.iter().map(|s| s.len()).max().unwrap_or(0).max(1);
                let data = strings
                    .iter()
                    .flat_map(|s| format!("{s:<len$}").into_bytes())
                    .collect();
                let dims = if *array {
                    vec![len, strings.len()]
                } else {
                    vec![len]
                };
                (-1, dims, data)
            }
        };
        r.push(code as u8);
        r.push(dims.len() as u8);
        r.extend(dims.iter().map(|&d| d as u8));
        r.extend_from_slice(&data);
        r.push(0);
        records.push(r);
    }
    for mut r in records {
        let off_at = 2 + r[0] as usize;
        let offset = (r.len() - off_at) as i16;
        r[off_at..off_at + 2].copy_from_slice(&p.put_i16(offset));
        out.extend_from_slice(&r);
    }
    out.extend_from_slice(&[0, 0]); // terminator record
    let blocks = out.len().div_ceil(512);
    out.resize(blocks * 512, 0);
    out[2] = blocks as u8;
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_every_type() {
        for p in [Processor::Intel, Processor::Dec, Processor::Mips] {
            let sec = encode(
                &[(1, "POINT"), (2, "ANALOG")],
                &[
                    (1, "USED", Value::Byte(vec![7], vec![])),
                    (1, "SCALE", Value::Float(vec![-0.25], vec![])),
                    (1, "FRAMES", Value::Int16(vec![-1], vec![])),
                    (
                        1,
                        "LABELS",
                        Value::Chars {
                            strings: vec!["A".into(), "LONGER".into()],
                            array: true,
                        },
                    ),
                    (
                        2,
                        "UNITS",
                        Value::Chars {
                            strings: vec!["mm".into()],
                            array: false,
                        },
                    ),
                ],
                p,
            );
            assert_eq!(sec[3], p.code());
            let params = decode(&sec, 512, p).unwrap();
            assert_eq!(params.get("point", "used").unwrap().count(), Some(7));
            assert_eq!(params.get("POINT", "SCALE").unwrap().number(0), Some(-0.25));
            // 16-bit counts are unsigned: -1 is 65535 frames.
            assert_eq!(params.get("POINT", "FRAMES").unwrap().count(), Some(65535));
            assert_eq!(params.get("POINT", "FRAMES").unwrap().i16(0), Some(-1));
            assert_eq!(
                params.get("POINT", "LABELS").unwrap().strings(),
                vec!["A", "LONGER"]
            );
            assert_eq!(params.get("ANALOG", "UNITS").unwrap().strings(), vec!["mm"]);
            assert!(params.get("POINT", "LABELS").unwrap().offset > 512);
        }
    }

    #[test]
    fn groups_after_params_and_garbage_records() {
        // A parameter before its group is still named.
        let sec = encode(
            &[(3, "LATE")],
            &[(3, "X", Value::Int16(vec![5], vec![]))],
            Processor::Intel,
        );
        let params = decode(&sec, 0, Processor::Intel).unwrap();
        assert_eq!(params.get("LATE", "X").unwrap().count(), Some(5));

        // A negative offset is an error naming the byte.
        let mut bad = sec.clone();
        let off_at = 4 + 2 + 4; // group record "LATE"
        bad[off_at..off_at + 2].copy_from_slice(&(-6i16).to_le_bytes());
        let e = decode(&bad, 512, Processor::Intel).unwrap_err();
        assert_eq!(e.at, 512 + off_at as u64);

        // Data running past the section is an error naming the parameter.
        let param_record = 4 + 2 + 4 + 2 + 1;
        for cut in param_record + 3..param_record + 9 {
            let e = decode(&sec[..cut], 0, Processor::Intel).unwrap_err();
            assert!(e.msg.contains("\"X\""), "{cut}: {}", e.msg);
        }
    }
}
