//! Deterministic mutations: of experiment files (values replaced by hostile ones through `--set`,
//! keys deleted or added, array elements duplicated or reversed, the text cut or garbled) and of
//! binary files (cuts, bit flips, overwritten bytes, huge counts written into headers).
//!
//! Every case draws from its own stream `(seed, Purpose::Test, stream, case)`, so case `k` of a
//! category is the same mutant however many cases run before or after it: the quick tests run
//! the first cases of the deep sweep (which may add mutations after the first).

use std::fmt;
use std::path::Path;

use ohd::sampling::{PathRng, Purpose};

/// The random choices of one case.
pub struct Draw(PathRng);

impl Draw {
    /// The stream of case `case` of the category numbered `stream`.
    pub fn new(seed: u64, stream: u64, case: u64) -> Self {
        Draw(PathRng::new(seed, Purpose::Test, stream, case))
    }

    /// A uniform index in `0..n` (`n ≥ 1`).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.0.uniform() * n as f64) as usize).min(n.saturating_sub(1))
    }

    /// A uniform number in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.0.uniform()
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.0.uniform() < p
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// One step of a key path: a table key or an array index.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    Key(String),
    Index(usize),
}

/// A key path as `--set` takes it (`layers.0.thickness_mm`).
pub fn dotted(path: &[Seg]) -> String {
    let parts: Vec<String> = path
        .iter()
        .map(|s| match s {
            Seg::Key(k) => k.clone(),
            Seg::Index(i) => i.to_string(),
        })
        .collect();
    parts.join(".")
}

/// Whether `--set` can address the path (no key holds a dot, `=`, a quote or a space).
fn settable(path: &[Seg]) -> bool {
    path.iter().all(|s| match s {
        Seg::Key(k) => !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'),
        Seg::Index(_) => true,
    })
}

/// Every node of `doc` below the root, depth first, with its path.
pub fn nodes(doc: &toml::Table) -> Vec<(Vec<Seg>, toml::Value)> {
    fn walk(v: &toml::Value, path: &mut Vec<Seg>, out: &mut Vec<(Vec<Seg>, toml::Value)>) {
        out.push((path.clone(), v.clone()));
        match v {
            toml::Value::Table(t) => {
                for (k, c) in t {
                    path.push(Seg::Key(k.clone()));
                    walk(c, path, out);
                    path.pop();
                }
            }
            toml::Value::Array(a) => {
                for (i, c) in a.iter().enumerate() {
                    path.push(Seg::Index(i));
                    walk(c, path, out);
                    path.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    for (k, v) in doc {
        walk(v, &mut vec![Seg::Key(k.clone())], &mut out);
    }
    out
}

fn node_mut<'a>(doc: &'a mut toml::Table, path: &[Seg]) -> Option<&'a mut toml::Value> {
    let (Seg::Key(first), rest) = path.split_first()? else { return None };
    let mut node = doc.get_mut(first)?;
    for s in rest {
        node = match (s, node) {
            (Seg::Key(k), toml::Value::Table(t)) => t.get_mut(k)?,
            (Seg::Index(i), toml::Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(node)
}

/// Remove the node at `path`; whether it was there.
fn remove(doc: &mut toml::Table, path: &[Seg]) -> bool {
    let Some((last, parent)) = path.split_last() else { return false };
    if parent.is_empty() {
        return matches!(last, Seg::Key(k) if doc.remove(k).is_some());
    }
    match (last, node_mut(doc, parent)) {
        (Seg::Key(k), Some(toml::Value::Table(t))) => t.remove(k).is_some(),
        (Seg::Index(i), Some(toml::Value::Array(a))) if *i < a.len() => {
            a.remove(*i);
            true
        }
        _ => false,
    }
}

/// Make every relative `file = "…"` of `doc` absolute against `dir`, so that a mutant written
/// elsewhere still finds the phase tables and VDB files its original names.
pub fn absolute_files(doc: &mut toml::Table, dir: &Path) {
    fn walk(v: &mut toml::Value, dir: &Path) {
        match v {
            toml::Value::Table(t) => {
                for (k, c) in t.iter_mut() {
                    match c {
                        toml::Value::String(s) if k == "file" && Path::new(s.as_str()).is_relative() => {
                            *s = dir.join(s.as_str()).display().to_string();
                        }
                        _ => walk(c, dir),
                    }
                }
            }
            toml::Value::Array(a) => a.iter_mut().for_each(|c| walk(c, dir)),
            _ => {}
        }
    }
    for (_, v) in doc.iter_mut() {
        walk(v, dir);
    }
}

/// The most nodes a long array is given (a hundred thousand numbers, or a thousand tables of up
/// to a hundred nodes each): mutations on top of mutations must not grow a document without bound.
pub const LONG_NODES: usize = 100_000;

/// The number of nodes of a value (itself and everything below it).
pub fn size(v: &toml::Value) -> usize {
    1 + match v {
        toml::Value::Table(t) => t.values().map(size).sum(),
        toml::Value::Array(a) => a.iter().map(size).sum(),
        _ => 0,
    }
}

/// One mutation of an experiment file.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// `--set KEY=VALUE` (a replaced value, or a key added).
    Set(String),
    /// The node at the path deleted.
    Delete(Vec<Seg>),
    /// A copy of element `i` appended to the array at the path (a second layer, detector, ROI…
    /// of the same name).
    Duplicate(Vec<Seg>, usize),
    /// The array at the path reversed.
    Reverse(Vec<Seg>),
    /// The node at the path replaced by a value `--set` cannot carry (a long array, or a key
    /// `--set` cannot address), with a short description of the value.
    Replace(Vec<Seg>, toml::Value, String),
    /// An edit of the file's text.
    Text(TextEdit),
}

impl fmt::Display for Mutation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Mutation::Set(s) => write!(f, "--set {}", shorten(s)),
            Mutation::Delete(p) => write!(f, "delete {}", dotted(p)),
            Mutation::Duplicate(p, i) => write!(f, "append a copy of {}.{i}", dotted(p)),
            Mutation::Reverse(p) => write!(f, "reverse {}", dotted(p)),
            Mutation::Replace(p, _, what) => write!(f, "replace {} by {what}", dotted(p)),
            Mutation::Text(e) => write!(f, "{e}"),
        }
    }
}

fn shorten(s: &str) -> String {
    if s.chars().count() <= 120 {
        s.to_string()
    } else {
        format!("{}… ({} chars)", s.chars().take(100).collect::<String>(), s.chars().count())
    }
}

/// An edit of a file's text.
#[derive(Debug, Clone)]
pub enum TextEdit {
    /// Cut after this many bytes.
    Truncate(usize),
    DeleteLine(usize),
    DuplicateLine(usize),
    /// A line of garbage inserted before line `n`.
    Insert(usize, String),
    /// A byte that is not UTF-8 written at this offset.
    BadByte(usize),
}

impl fmt::Display for TextEdit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TextEdit::Truncate(n) => write!(f, "text cut after byte {n}"),
            TextEdit::DeleteLine(n) => write!(f, "text line {} deleted", n + 1),
            TextEdit::DuplicateLine(n) => write!(f, "text line {} duplicated", n + 1),
            TextEdit::Insert(n, s) => write!(f, "text line {s:?} inserted before line {}", n + 1),
            TextEdit::BadByte(n) => write!(f, "byte 0xff written at offset {n}"),
        }
    }
}

impl TextEdit {
    fn draw(d: &mut Draw, text: &str) -> TextEdit {
        let lines = text.lines().count().max(1);
        match d.below(5) {
            0 => TextEdit::Truncate(d.below(text.len())),
            1 => TextEdit::DeleteLine(d.below(lines)),
            2 => TextEdit::DuplicateLine(d.below(lines)),
            3 => {
                let garbage = ["= = =", "[[", "[run]", "x = ", "\"\"\"", "schema_version = 1", "\u{0}", "[[layers]]"];
                TextEdit::Insert(d.below(lines + 1), d.pick(&garbage).to_string())
            }
            _ => TextEdit::BadByte(d.below(text.len())),
        }
    }

    /// The edited bytes.
    pub fn apply(&self, text: &str) -> Vec<u8> {
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        match self {
            TextEdit::Truncate(n) => return text.as_bytes()[..*n].to_vec(),
            TextEdit::BadByte(n) => {
                let mut b = text.as_bytes().to_vec();
                b[*n] = 0xff;
                return b;
            }
            TextEdit::DeleteLine(n) => {
                lines.remove(*n);
            }
            TextEdit::DuplicateLine(n) => lines.insert(*n, lines[*n].clone()),
            TextEdit::Insert(n, s) => lines.insert(*n, s.clone()),
        }
        (lines.join("\n") + "\n").into_bytes()
    }
}

/// Values hostile to any key, as TOML literals.
const ANY: &[&str] = &[
    "0",
    "-1",
    "-0.0",
    "1e-300",
    "-1e-300",
    "5e-324",
    "1e300",
    "-1e300",
    "1.7976931348623157e308",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "9223372036854775807",
    "-9223372036854775808",
    "4294967296",
    "\"\"",
    "\"nan\"",
    "true",
    "[]",
    "{}",
    "[nan]",
    "[[]]",
    "1979-05-27T07:32:00Z",
];

/// Hostile numbers only: what a run is most often fed.
const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1e-300",
    "-1e-300",
    "5e-324",
    "1e300",
    "-1e300",
    "1e308",
    "nan",
    "inf",
    "-inf",
    "9223372036854775807",
];

/// A hostile literal for a node holding `v` (key `key`); `numeric` leans to numbers.
fn hostile_value(d: &mut Draw, key: &str, v: &toml::Value, numeric: bool) -> String {
    let literal = |v: toml::Value| v.to_string();
    let typed: Vec<String> = match v {
        toml::Value::Integer(n) => {
            let n = *n;
            vec![
                literal(toml::Value::Integer(n.saturating_add(1))),
                literal(toml::Value::Integer(n.saturating_sub(1))),
                literal(toml::Value::Integer(n.saturating_mul(1000))),
                literal(toml::Value::Integer(n.saturating_mul(1_000_000_000))),
                literal(toml::Value::Integer(n.saturating_neg())),
                format!("{n}.5"),
                "2147483648".into(),
                "65536".into(),
            ]
        }
        toml::Value::Float(x) => {
            let x = *x;
            [1e6, 1e-6, 1e12, 1e-12, -1.0, 1.0 + 1e-15, 1e150]
                .iter()
                .map(|k| literal(toml::Value::Float(x * k)))
                .chain([literal(toml::Value::Float(x + 1.0))])
                .collect()
        }
        toml::Value::String(_) if key == "file" => {
            // An endless file and a directory of the tests' own, never the machine's.
            let special = crate::support::special::special();
            let own = [special.endless().display().to_string(), special.dir.display().to_string()];
            own.iter()
                .map(String::as_str)
                .chain(["/nonexistent/none.vdb", ".", ""])
                .map(|p| format!("\"{p}\""))
                .collect()
        }
        toml::Value::String(s) => vec![
            "\"\"".into(),
            format!("\"{}\"", "a".repeat(8000)),
            literal(toml::Value::String(format!("{s}x"))),
            literal(toml::Value::String(s.to_uppercase())),
            "\"\\u0000\"".into(),
            "\"../../../../../../../../nonexistent/passwd\"".into(),
        ],
        toml::Value::Boolean(b) => vec![(!b).to_string(), "\"true\"".into(), "1".into()],
        toml::Value::Array(a) => {
            let mut shorter = a.clone();
            shorter.pop();
            let mut longer = a.clone();
            longer.extend(a.last().cloned());
            let nans = vec![toml::Value::Float(f64::NAN); a.len()];
            let negative = vec![toml::Value::Float(-1.0); a.len()];
            let zeros = vec![toml::Value::Integer(0); a.len()];
            [shorter, longer, nans, negative, zeros].into_iter().map(|x| literal(toml::Value::Array(x))).collect()
        }
        toml::Value::Table(t) => {
            let mut fewer = t.clone();
            if let Some(k) = fewer.keys().next().cloned() {
                fewer.remove(&k);
            }
            vec!["{}".into(), "1".into(), "\"table\"".into(), literal(toml::Value::Table(fewer))]
        }
        toml::Value::Datetime(_) => vec!["0".into()],
    };
    let is_number = matches!(v, toml::Value::Integer(_) | toml::Value::Float(_));
    if numeric && is_number {
        if d.chance(0.5) { d.pick(&typed).clone() } else { d.pick(NUMBERS).to_string() }
    } else if d.chance(0.6) {
        d.pick(&typed).clone()
    } else {
        d.pick(ANY).to_string()
    }
}

/// How mutations are drawn: `ohd check` sweeps (every kind of mutation) or runs (mostly hostile
/// numbers, which validation is likelier to let through).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Aim {
    Check,
    Run,
}

/// Draw one mutation of `doc` (the document as mutated so far; `text` its file's text).
pub fn draw_mutation(d: &mut Draw, doc: &toml::Table, text: &str, aim: Aim, text_edits: bool) -> Mutation {
    let all = nodes(doc);
    if all.is_empty() {
        return Mutation::Set("zz_unknown=1".into());
    }
    let roll = d.below(100);
    let (set, unknown, delete, duplicate, reverse, long) = match aim {
        Aim::Check => (52, 62, 74, 82, 85, 88),
        Aim::Run => (70, 80, 88, 96, 98, 100),
    };
    if roll >= long && text_edits {
        return Mutation::Text(TextEdit::draw(d, text));
    }
    if roll < set {
        // Numbers are the run's main diet: pick among numeric leaves most of the time.
        let numeric: Vec<&(Vec<Seg>, toml::Value)> =
            all.iter().filter(|(_, v)| matches!(v, toml::Value::Integer(_) | toml::Value::Float(_))).collect();
        let (path, v) = if aim == Aim::Run && !numeric.is_empty() && d.chance(0.85) {
            (*d.pick(&numeric)).clone()
        } else {
            d.pick(&all).clone()
        };
        let key = match path.last() {
            Some(Seg::Key(k)) => k.clone(),
            _ => String::new(),
        };
        let value = hostile_value(d, &key, &v, aim == Aim::Run);
        if settable(&path) {
            return Mutation::Set(format!("{}={value}", dotted(&path)));
        }
        let parsed = format!("v = {value}").parse::<toml::Table>().ok().and_then(|mut t| t.remove("v"));
        return Mutation::Replace(path, parsed.unwrap_or(toml::Value::String(value.clone())), shorten(&value));
    }
    if roll < unknown && d.chance(0.5) {
        // A copy of a named table beside it (an unused medium, most often) with one value made
        // hostile: validation must reach what the run does not use.
        let named: Vec<&(Vec<Seg>, toml::Value)> = all
            .iter()
            .filter(|(p, v)| v.is_table() && p.len() >= 2 && settable(p) && matches!(p.last(), Some(Seg::Key(_))))
            .collect();
        let media: Vec<&(Vec<Seg>, toml::Value)> =
            named.iter().copied().filter(|(p, _)| p.len() == 2 && p[0] == Seg::Key("media".into())).collect();
        let pool = if !media.is_empty() && (named.len() == media.len() || d.chance(0.7)) { media } else { named };
        if !pool.is_empty() {
            let (path, v) = (*d.pick(&pool)).clone();
            let mut copy = v.as_table().cloned().unwrap_or_default();
            let leaves: Vec<(Vec<Seg>, toml::Value)> =
                nodes(&copy).into_iter().filter(|(p, v)| !v.is_table() && settable(p)).collect();
            if !leaves.is_empty() {
                let (leaf, lv) = d.pick(&leaves).clone();
                let key = match leaf.last() {
                    Some(Seg::Key(k)) => k.clone(),
                    _ => String::new(),
                };
                let value = hostile_value(d, &key, &lv, aim == Aim::Run);
                let _ = ohd::config::apply_set(&mut copy, &format!("{}={value}", dotted(&leaf)));
            }
            let parent = dotted(&path[..path.len() - 1]);
            return Mutation::Set(format!("{parent}.zz_copy={}", toml::Value::Table(copy)));
        }
    }
    if roll < unknown {
        let tables: Vec<&Vec<Seg>> = all.iter().filter(|(p, v)| v.is_table() && settable(p)).map(|(p, _)| p).collect();
        return if tables.is_empty() || d.chance(0.2) {
            Mutation::Set("zz_unknown=1".into())
        } else {
            let table: &&Vec<Seg> = d.pick(&tables);
            Mutation::Set(format!("{}.zz_unknown=1", dotted(table)))
        };
    }
    let arrays: Vec<(&Vec<Seg>, usize)> =
        all.iter().filter_map(|(p, v)| v.as_array().filter(|a| !a.is_empty()).map(|a| (p, a.len()))).collect();
    if roll < delete || arrays.is_empty() {
        return Mutation::Delete(d.pick(&all).0.clone());
    }
    if roll < duplicate {
        // Arrays of tables (layers, detectors, regions, ROIs) first: duplicated names.
        let of_tables: Vec<(&Vec<Seg>, usize)> = arrays
            .iter()
            .copied()
            .filter(|(p, _)| all.iter().any(|(q, v)| v.is_table() && q.len() == p.len() + 1 && q.starts_with(p)))
            .collect();
        let (p, n) = if !of_tables.is_empty() && d.chance(0.7) { *d.pick(&of_tables) } else { *d.pick(&arrays) };
        return Mutation::Duplicate(p.clone(), d.below(n));
    }
    if roll < reverse {
        return Mutation::Reverse(d.pick(&arrays).0.clone());
    }
    // A long array where a short one stands: a thousand layers, detectors or pointings, or a
    // hundred thousand numbers.
    let (p, _) = *d.pick(&arrays);
    let a = match all.iter().find(|(q, _)| q == p) {
        Some((_, toml::Value::Array(a))) => a.clone(),
        _ => Vec::new(),
    };
    let scalars = a.iter().all(|v| !v.is_table() && !v.is_array());
    let n = if scalars && d.chance(0.5) { 100_000 } else { 1000 };
    // At most LONG_NODES nodes (an array of tables already made long stays in bounds).
    let per = a.iter().map(size).sum::<usize>().div_ceil(a.len().max(1)).max(1);
    let n = n.min(LONG_NODES / per).max(a.len() + 1);
    let long: Vec<toml::Value> = a.iter().cycle().take(n).cloned().collect();
    Mutation::Replace(p.clone(), toml::Value::Array(long), format!("its elements repeated to {n}"))
}

/// Apply a mutation other than a text edit to `doc` (`--set` as ohd applies it). Returns false
/// if the mutation does not apply (ohd then reports the `--set` error itself).
pub fn apply(doc: &mut toml::Table, m: &Mutation) -> bool {
    match m {
        Mutation::Set(s) => ohd::config::apply_set(doc, s).is_ok(),
        Mutation::Delete(p) => remove(doc, p),
        Mutation::Duplicate(p, i) => match node_mut(doc, p) {
            Some(toml::Value::Array(a)) if *i < a.len() => {
                let c = a[*i].clone();
                a.push(c);
                true
            }
            _ => false,
        },
        Mutation::Reverse(p) => match node_mut(doc, p) {
            Some(toml::Value::Array(a)) => {
                a.reverse();
                true
            }
            _ => false,
        },
        Mutation::Replace(p, v, _) => match node_mut(doc, p) {
            Some(n) => {
                *n = v.clone();
                true
            }
            None => false,
        },
        Mutation::Text(_) => false,
    }
}

/// One corruption of a binary (or text) file.
#[derive(Debug, Clone)]
pub enum Corruption {
    /// Cut after this many bytes.
    Truncate(usize),
    /// Bit `1` of byte `0` flipped.
    Flip(usize, u8),
    /// Bytes overwritten from an offset.
    Overwrite(usize, Vec<u8>),
    /// A little-endian count written at a (4-aligned) offset of the header or topology.
    Count(usize, u64, usize),
    /// Bytes appended.
    Append(Vec<u8>),
}

impl fmt::Display for Corruption {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Corruption::Truncate(n) => write!(f, "cut after byte {n}"),
            Corruption::Flip(at, bit) => write!(f, "bit {bit} of byte {at} flipped"),
            Corruption::Overwrite(at, b) => write!(f, "bytes {at}..{} overwritten with {b:02x?}", at + b.len()),
            Corruption::Count(at, v, w) => {
                let v = if *w < 8 { v & ((1u64 << (8 * w)) - 1) } else { *v };
                write!(f, "{w}-byte value {v:#x} written at byte {at}")
            }
            Corruption::Append(b) => write!(f, "{} bytes appended", b.len()),
        }
    }
}

impl Corruption {
    /// Draw a corruption of a file of `len` bytes whose header and topology lie in the first
    /// `header` bytes.
    pub fn draw(d: &mut Draw, len: usize, header: usize) -> Corruption {
        let head = header.min(len).max(1);
        match d.below(10) {
            0 | 1 => Corruption::Truncate(if d.chance(0.5) { d.below(head) } else { d.below(len) }),
            2..=4 => {
                let at = if d.chance(0.5) { d.below(head) } else { d.below(len) };
                Corruption::Flip(at, d.below(8) as u8)
            }
            5 | 6 => {
                let n = 1 + d.below(8);
                let at = d.below(len.saturating_sub(n).max(1));
                let fill = [0x00, 0xff, 0x7f, 0x80];
                let bytes = (0..n).map(|_| if d.chance(0.5) { *d.pick(&fill) } else { d.below(256) as u8 }).collect();
                Corruption::Overwrite(at, bytes)
            }
            7 | 8 => {
                let values = [
                    u64::MAX,
                    u32::MAX as u64,
                    i32::MAX as u64,
                    1 << 31,
                    1 << 40,
                    0,
                    0x7ff0_0000_0000_0000, // +inf as f64 bits
                    0x7ff8_0000_0000_0000, // NaN as f64 bits
                ];
                let width = if d.chance(0.5) { 4 } else { 8 };
                let at = 4 * d.below(head.saturating_sub(width).max(1) / 4 + 1);
                Corruption::Count(at, *d.pick(&values), width)
            }
            _ => {
                let n = 1 + d.below(64);
                Corruption::Append((0..n).map(|_| d.below(256) as u8).collect())
            }
        }
    }

    pub fn apply(&self, bytes: &[u8]) -> Vec<u8> {
        let mut b = bytes.to_vec();
        match self {
            Corruption::Truncate(n) => b.truncate(*n),
            Corruption::Flip(at, bit) => {
                if let Some(x) = b.get_mut(*at) {
                    *x ^= 1 << bit;
                }
            }
            Corruption::Overwrite(at, w) => {
                for (i, x) in w.iter().enumerate() {
                    if let Some(y) = b.get_mut(at + i) {
                        *y = *x;
                    }
                }
            }
            Corruption::Count(at, v, width) => {
                for (i, x) in v.to_le_bytes().iter().take(*width).enumerate() {
                    if let Some(y) = b.get_mut(at + i) {
                        *y = *x;
                    }
                }
            }
            Corruption::Append(extra) => b.extend_from_slice(extra),
        }
        b
    }
}
