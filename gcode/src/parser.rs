//! RS274/NGC text → [`Program`].

use interp_core::nurbs::{NurbsError, validate_program_curve};

use crate::Units;
use crate::error::{ParseError, ParseErrorKind};
use crate::expr::{Cursor, NEAR_INT_TOL, Parameters, Target};
use crate::program::{
    ArcMove, BlockKind, Feed, LinearMove, NurbsMove, Orientation, PathControl, Plane, Point,
    Program, ProgramBlock, RapidMove, Rotary, SpindleRotation, ToolControl,
};

/// LinuxCNC's `RADIUS_TOLERANCE_INCH`: arcs with a smaller radius are refused, inch.
pub const RADIUS_TOLERANCE_INCH: f64 = 0.00005;
/// LinuxCNC's `CENTER_ARC_RADIUS_TOLERANCE_INCH` (`2·0.001·√2`): the start and end
/// radii of a centre-format arc may differ by this (or by 0.1 %), inch.
pub const CENTER_ARC_RADIUS_TOLERANCE_INCH: f64 = 2.0 * 0.001 * core::f64::consts::SQRT_2;
/// LinuxCNC's `CENTER_ARC_RADIUS_TOLERANCE_MM` (`2·0.01·√2`), mm.
pub const CENTER_ARC_RADIUS_TOLERANCE_MM: f64 = 2.0 * 0.01 * core::f64::consts::SQRT_2;
/// LinuxCNC's `SPIRAL_RELATIVE_TOLERANCE`: relative radius difference allowed
/// (with the absolute one above); beyond 100× the absolute one, always an error.
pub const SPIRAL_RELATIVE_TOLERANCE: f64 = 0.001;
/// Multiple of the absolute tolerance beyond which a radius difference is
/// always an error (LinuxCNC's `spiral_abs_tolerance * 100`).
pub const SPIRAL_ABS_HARD_FACTOR: f64 = 100.0;
/// LinuxCNC treats `half chord / R` above `1 − TINY` as a semicircle.
pub const ARC_R_TINY: f64 = 1e-12;
/// The smallest G5.2 order LinuxCNC accepts in `L` (smaller values keep order 3).
pub const G5_2_DEFAULT_ORDER: usize = 3;

/// Bytes per block assumed when reserving the block vector up front.
const BYTES_PER_BLOCK_GUESS: usize = 32;

/// Parses RS274/NGC text into a [`Program`] (mm, absolute coordinates).
///
/// Stops at `M2`/`M30` or at a second `%` line. Never panics.
pub fn parse(text: &str) -> Result<Program, ParseError> {
    parse_from(text, [0.0; 3])
}

/// Parses as [`parse`] does, with the machine at `start` (mm) before the
/// first line instead of the origin: relative moves (G91) and the first move
/// start there, so a program is converted from where the machine is. The
/// rotary axes start at 0.
pub fn parse_from(text: &str, start: Point) -> Result<Program, ParseError> {
    parse_from_axes(text, [start[0], start[1], start[2], 0.0, 0.0, 0.0])
}

/// Parses as [`parse_from`] does, with the machine's axes `[X, Y, Z, A, B,
/// C]` (mm and degrees, as interp-core's setpoints) before the first line.
pub fn parse_from_axes(text: &str, start: [f64; 6]) -> Result<Program, ParseError> {
    let mut p = Parser {
        pos: [start[0], start[1], start[2]],
        rotary: [Some(start[3]), Some(start[4]), Some(start[5])],
        ..Parser::default()
    };
    // A G-code line is rarely shorter than this: one reservation instead of
    // repeated growth (and copies) on large programs.
    p.blocks.reserve(text.len() / BYTES_PER_BLOCK_GUESS);
    // Windows editors and CAM posts start UTF-8 files with a byte-order mark.
    let text = text.strip_prefix('\u{FEFF}').unwrap_or(text);
    let mut line_no: u32 = 0;
    for raw in lines(text) {
        line_no = line_no.saturating_add(1);
        match p.line(raw, line_no) {
            Ok(true) => {}
            Ok(false) => break,
            Err((byte, kind)) => {
                // A NURBS defect is reported on the line of the offending point or knot.
                let (line_no, raw) = match p.error_line.take() {
                    Some(l) => (l, lines(text).nth(l as usize - 1).unwrap_or("")),
                    None => (line_no, raw),
                };
                let byte = byte.min(raw.len());
                // Columns count characters; `byte` may sit inside one.
                let column = raw
                    .char_indices()
                    .take_while(|(i, _)| *i < byte)
                    .count()
                    .saturating_add(1);
                return Err(ParseError {
                    line: line_no,
                    column: u32::try_from(column).unwrap_or(u32::MAX),
                    kind,
                });
            }
        }
    }
    p.finish(line_no)
}

/// The lines of a program without their ends: LF, CR LF, or a CR alone (the
/// old Macintosh convention some CAM posts still write).
fn lines(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = Some(text);
    core::iter::from_fn(move || {
        let t = rest?;
        match t.bytes().position(|b| b == b'\n' || b == b'\r') {
            Some(i) => {
                let end = if t.as_bytes()[i] == b'\r' && t.as_bytes().get(i + 1) == Some(&b'\n') {
                    i + 2
                } else {
                    i + 1
                };
                rest = Some(&t[end..]);
                Some(&t[..i])
            }
            None => {
                rest = None;
                Some(t)
            }
        }
    })
}

type LineResult<T> = Result<T, (usize, ParseErrorKind)>;

/// Letters that may carry a value on a line (not G and M).
const LETTERS: usize = 26;

/// The axis words: X Y Z and the rotary A B C.
const AXIS_WORDS: [u8; 6] = [b'x', b'y', b'z', b'a', b'b', b'c'];

fn idx(c: u8) -> usize {
    (c - b'a') as usize
}

/// Modal groups of G codes (LinuxCNC numbering), `code` in tenths (G5.2 = 52).
fn g_group(code: u32) -> Option<(u8, &'static str)> {
    Some(match code {
        0 | 10 | 20 | 22 | 30 | 50 | 51 | 52 | 53 | 62 | 800 => (1, "motion"),
        40 => (0, "non-modal"),
        170 | 180 | 190 => (2, "plane"),
        900 | 910 => (3, "distance mode"),
        901 | 911 => (4, "arc distance mode"),
        930 | 940 => (5, "feed rate mode"),
        200 | 210 => (6, "units"),
        400 => (7, "cutter compensation"),
        434 | 435 | 490 => (8, "tool length offset"),
        540 => (12, "coordinate system"),
        610 | 611 | 640 => (13, "path control"),
        960 | 970 => (14, "spindle speed mode"),
        _ => return None,
    })
}

/// RS274/NGC codes interpd knows but does not implement, `code` in tenths:
/// what they are, for the error (their D/H words are read so that the code,
/// not the word, is named).
fn unsupported_g(code: u32) -> Option<&'static str> {
    Some(match code {
        410 | 411 | 420 | 421 => "cutter radius compensation",
        430..=432 => "tool length offsets",
        280 | 281 | 300 | 301 => "return to a predefined position",
        730 | 760 | 810..=890 => "canned cycles",
        _ => return None,
    })
}

fn m_group(code: u32) -> Option<(u8, &'static str)> {
    Some(match code {
        0 | 1 | 2 | 30 => (4, "stopping"),
        6 => (6, "tool change"),
        3..=5 => (7, "spindle"),
        7..=9 => (8, "coolant"),
        _ => return None,
    })
}

fn g_name(code: u32) -> String {
    if code.is_multiple_of(10) {
        format!("G{}", code / 10)
    } else {
        format!("G{}.{}", code / 10, code % 10)
    }
}

/// Motion mode (modal group 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Motion {
    Rapid,
    Linear,
    ArcCw,
    ArcCcw,
    Cubic,
    Quadratic,
    G5_2,
    G6_2,
}

/// The words of one line.
#[derive(Debug)]
struct Words {
    values: [f64; LETTERS],
    cols: [usize; LETTERS],
    present: u32,
    g: [(u32, usize); 16],
    g_len: usize,
    m: [(u32, usize); 8],
    m_len: usize,
    assignments: Vec<(Target, f64)>,
}

impl Default for Words {
    fn default() -> Self {
        Self::new()
    }
}

impl Words {
    fn new() -> Self {
        Words {
            values: [0.0; LETTERS],
            cols: [0; LETTERS],
            present: 0,
            g: [(0, 0); 16],
            g_len: 0,
            m: [(0, 0); 8],
            m_len: 0,
            assignments: Vec::new(),
        }
    }
    fn has(&self, c: u8) -> bool {
        self.present & (1 << idx(c)) != 0
    }
    fn get(&self, c: u8) -> Option<f64> {
        self.has(c).then(|| self.values[idx(c)])
    }
    /// Column of word `c`, or 0 (the line's start) when it is absent.
    fn col(&self, c: u8) -> usize {
        if self.has(c) { self.cols[idx(c)] } else { 0 }
    }
    fn gs(&self) -> &[(u32, usize)] {
        &self.g[..self.g_len]
    }
    fn ms(&self) -> &[(u32, usize)] {
        &self.m[..self.m_len]
    }
}

/// A G5.2 curve being collected.
#[derive(Debug)]
struct G5Curve {
    first_line: u32,
    plane: Plane,
    order: usize,
    start: Point,
    points: Vec<Point>,
    weights: Vec<f64>,
    /// (line, column) of each control point.
    sources: Vec<(u32, usize)>,
}

/// A G6.2 curve being collected: every line is an entry with a knot; all but
/// the last `order` entries are control points (LinuxCNC's reading).
#[derive(Debug)]
struct G6Curve {
    first_line: u32,
    first_col: usize,
    order: usize,
    start: Point,
    points: Vec<Point>,
    weights: Vec<f64>,
    knots: Vec<f64>,
    /// (line, column) of each entry (control point and knot).
    sources: Vec<(u32, usize)>,
    /// Rotary coordinates of each entry.
    rotary: Vec<Rotary>,
    /// The tool vector of each entry (G43.5, U V W; `None`: not given,
    /// the current one for a control point without coordinates).
    vectors: Vec<Option<[f64; 3]>>,
    /// Whether the curve's control point lines give U V W (set by the
    /// first one), and its line.
    vectors_given: Option<(bool, u32)>,
}

#[derive(Debug)]
struct Parser {
    blocks: Vec<ProgramBlock>,
    params: Parameters,
    pos: Point,
    units: Units,
    plane: Plane,
    absolute: bool,
    arc_absolute: bool,
    inverse_time: bool,
    /// Feed, mm/min (G94) or 1/min (G93).
    feed: f64,
    speed: f64,
    rotation: SpindleRotation,
    css: bool,
    tool: u32,
    /// Rotary axes A B C, degrees (`None`: unknown, after G43.5).
    rotary: Rotary,
    /// G43.4 / G43.5 / G49.
    tool_control: ToolControl,
    /// The G43.5 tool vector (`None`: the machine's, no I J K yet).
    tool_vector: Option<[f64; 3]>,
    motion: Option<Motion>,
    g5: Option<G5Curve>,
    g6: Option<G6Curve>,
    /// Last G5 cubic's second control point offset (P, Q) from its end, for an I/J-less G5.
    last_cubic_pq: Option<[f64; 2]>,
    seen_percent: bool,
    /// The word table of the previous line, reused.
    spare_words: Option<Box<Words>>,
    /// Set with an error that belongs to an earlier line than the current one.
    error_line: Option<u32>,
    /// A non-blank line has been read (a '%' may only come before).
    seen_content: bool,
    /// Normalised line and source byte offsets, reused.
    buf: Vec<u8>,
    cols: Vec<usize>,
}

impl Default for Parser {
    fn default() -> Self {
        Parser {
            blocks: Vec::new(),
            params: Parameters::default(),
            pos: [0.0; 3],
            units: Units::Millimetres,
            plane: Plane::Xy,
            absolute: true,
            arc_absolute: false,
            inverse_time: false,
            feed: 0.0,
            speed: 0.0,
            rotation: SpindleRotation::Stopped,
            css: false,
            tool: 0,
            rotary: [Some(0.0); 3],
            tool_control: ToolControl::Off,
            tool_vector: None,
            motion: None,
            g5: None,
            g6: None,
            last_cubic_pq: None,
            seen_percent: false,
            spare_words: None,
            error_line: None,
            seen_content: false,
            buf: Vec::with_capacity(128),
            cols: Vec::with_capacity(128),
        }
    }
}

fn err<T>(col: usize, kind: ParseErrorKind) -> LineResult<T> {
    Err((col, kind))
}

fn near_int(v: f64) -> Option<i64> {
    let r = v.round();
    ((v - r).abs() < NEAR_INT_TOL && r.abs() < 1e15).then_some(r as i64)
}

impl Parser {
    /// Drops comments and blanks, lower-cases; `Ok(false)` for a block-delete line.
    fn normalise(&mut self, raw: &str) -> LineResult<bool> {
        self.buf.clear();
        self.cols.clear();
        let bytes = raw.as_bytes();
        let mut i = 0;
        while i < bytes.len() {
            let c = bytes[i];
            // Fast path for what most of a program is: letters, digits, signs,
            // points and blanks.
            if c.is_ascii_alphanumeric() || c == b'.' || c == b'-' {
                self.buf.push(c | ((c.is_ascii_uppercase() as u8) << 5));
                self.cols.push(i);
                i += 1;
                continue;
            }
            if c == b' ' {
                i += 1;
                continue;
            }
            match c {
                b' ' | b'\t' => {}
                b';' => break,
                b'(' => {
                    let close = bytes[i + 1..].iter().position(|&b| b == b')' || b == b'(');
                    match close.map(|k| (k, bytes[i + 1 + k])) {
                        Some((k, b')')) => i += k + 1,
                        Some((k, _)) => {
                            return err(
                                i + 1 + k,
                                ParseErrorKind::Expression("nested comment".into()),
                            );
                        }
                        None => {
                            return err(
                                i,
                                ParseErrorKind::Expression("comment without closing ')'".into()),
                            );
                        }
                    }
                }
                b'/' if self.buf.is_empty() => return Ok(false),
                _ if c.is_ascii_graphic() => {
                    self.buf.push(c.to_ascii_lowercase());
                    self.cols.push(i);
                }
                _ => {
                    let ch = raw[i..].chars().next().unwrap_or('?');
                    return err(i, ParseErrorKind::UnexpectedChar(ch));
                }
            }
            i += 1;
        }
        Ok(true)
    }

    /// One source line; `Ok(false)` ends the program.
    fn line(&mut self, raw: &str, line_no: u32) -> LineResult<bool> {
        let first_content = !self.seen_content;
        if !raw.trim().is_empty() {
            self.seen_content = true;
        }
        if !self.normalise(raw)? || self.buf.is_empty() {
            return Ok(true);
        }
        if self.buf[0] == b'%' {
            if self.buf.len() > 1 {
                return err(
                    self.cols[1],
                    ParseErrorKind::UnexpectedChar(self.buf[1] as char),
                );
            }
            // As LinuxCNC: '%' may open the program on its first line and then
            // ends it; anywhere else it is a bad character.
            if self.seen_percent {
                return Ok(false);
            }
            if !first_content {
                return err(self.cols[0], ParseErrorKind::UnexpectedChar('%'));
            }
            self.seen_percent = true;
            return Ok(true);
        }
        // The word table is reused from line to line (it is large to copy).
        let mut words = self.spare_words.take().unwrap_or_default();
        self.read_words(&mut words)
            .map_err(|(i, k)| (self.src_col(i), k))?;
        let go_on = self.execute(&words, line_no)?;
        for (t, v) in words.assignments.drain(..) {
            self.params.set(t, v);
        }
        self.spare_words = Some(words);
        Ok(go_on)
    }

    fn src_col(&self, i: usize) -> usize {
        self.cols
            .get(i)
            .copied()
            .unwrap_or_else(|| self.cols.last().map_or(0, |c| c + 1))
    }

    fn read_words(&self, w: &mut Words) -> LineResult<()> {
        w.present = 0;
        w.g_len = 0;
        w.m_len = 0;
        w.assignments.clear();
        let mut cur = Cursor {
            buf: &self.buf,
            pos: 0,
            params: &self.params,
        };
        while let Some(&c) = cur.buf.get(cur.pos) {
            let at = cur.pos;
            if c == b'#' {
                cur.pos += 1;
                let t = cur.parameter_target(0)?;
                if cur.buf.get(cur.pos) != Some(&b'=') {
                    return err(
                        cur.pos,
                        ParseErrorKind::Expression(
                            "expected '=' after a parameter at the start of a word".into(),
                        ),
                    );
                }
                cur.pos += 1;
                let v = cur.real_value(0)?;
                w.assignments.push((t, v));
                continue;
            }
            if !c.is_ascii_lowercase() {
                return err(at, ParseErrorKind::UnexpectedChar(c as char));
            }
            match c {
                // A line that is only a program number (`O1234`, how Fanuc
                // programs begin) names the program: nothing to run.
                b'o' if at == 0
                    && cur.buf.len() > 1
                    && cur.buf[1..].iter().all(u8::is_ascii_digit) =>
                {
                    return Ok(());
                }
                b'o' => {
                    return err(
                        at,
                        ParseErrorKind::Unsupported(
                            "O-words (subroutines and control flow)".into(),
                        ),
                    );
                }
                b'e' => {
                    return err(
                        at,
                        ParseErrorKind::UnknownWord(c.to_ascii_uppercase() as char),
                    );
                }
                _ => {}
            }
            cur.pos += 1;
            let v = cur.real_value(0)?;
            if !v.is_finite() {
                return err(
                    at,
                    ParseErrorKind::BadValue(format!(
                        "{} word is not finite",
                        c.to_ascii_uppercase() as char
                    )),
                );
            }
            match c {
                b'g' => {
                    let code = (v * 10.0).round();
                    if !((v * 10.0 - code).abs() < 1e-6) || !(0.0..=9999.0).contains(&code) {
                        return err(at, ParseErrorKind::UnknownCode(format!("G{v}")));
                    }
                    let code = code as u32;
                    if w.g_len == w.g.len() {
                        return err(
                            at,
                            ParseErrorKind::ConflictingArguments(
                                "too many G codes on one line".into(),
                            ),
                        );
                    }
                    w.g[w.g_len] = (code, at);
                    w.g_len += 1;
                }
                b'm' => {
                    let Some(code) = near_int(v).filter(|c| (0..=9999).contains(c)) else {
                        return err(at, ParseErrorKind::UnknownCode(format!("M{v}")));
                    };
                    if w.m_len == w.m.len() {
                        return err(
                            at,
                            ParseErrorKind::ConflictingArguments(
                                "too many M codes on one line".into(),
                            ),
                        );
                    }
                    w.m[w.m_len] = (code as u32, at);
                    w.m_len += 1;
                }
                _ => {
                    if w.has(c) {
                        return err(
                            at,
                            ParseErrorKind::DuplicateWord(c.to_ascii_uppercase() as char),
                        );
                    }
                    w.present |= 1 << idx(c);
                    w.values[idx(c)] = v;
                    w.cols[idx(c)] = at;
                }
            }
        }
        // Word columns refer to the source line from here on.
        for (i, c) in w.cols.iter_mut().enumerate() {
            if w.present & (1 << i) != 0 {
                *c = self.src_col(*c);
            }
        }
        for g in w.g[..w.g_len].iter_mut() {
            g.1 = self.src_col(g.1);
        }
        for m in w.m[..w.m_len].iter_mut() {
            m.1 = self.src_col(m.1);
        }
        Ok(())
    }

    fn finish(self, line_no: u32) -> Result<Program, ParseError> {
        let open = |line: u32, what: &str| ParseError {
            line,
            column: 1,
            kind: ParseErrorKind::NurbsSequence(format!(
                "{what} curve still open at the end of the program (started on line {line}, program ends on line {line_no})"
            )),
        };
        if let Some(c) = &self.g5 {
            return Err(open(c.first_line, "G5.2"));
        }
        if let Some(c) = &self.g6 {
            return Err(open(c.first_line, "G6.2"));
        }
        Ok(Program {
            blocks: self.blocks,
        })
    }

    fn push(&mut self, line: u32, kind: BlockKind) {
        self.blocks.push(ProgramBlock { line, kind });
    }

    fn len(&self, v: f64) -> f64 {
        self.units.to_mm(v)
    }

    /// The end point from X Y Z against `base` (the current position, or a
    /// NURBS start: LinuxCNC does not move its position while collecting).
    fn target(&self, w: &Words, base: Point) -> Point {
        let mut p = base;
        for (i, c) in [b'x', b'y', b'z'].into_iter().enumerate() {
            if let Some(v) = w.get(c) {
                let v = self.len(v);
                p[i] = if self.absolute { v } else { base[i] + v };
            }
        }
        p
    }

    /// The rotary positions from A B C against `base` (degrees: G20 does
    /// not scale them; G91 adds them).
    fn rotary_target(&self, w: &Words, base: Rotary) -> LineResult<Rotary> {
        let mut r = base;
        for (i, c) in [b'a', b'b', b'c'].into_iter().enumerate() {
            if let Some(v) = w.get(c) {
                r[i] = if self.absolute {
                    Some(v)
                } else {
                    match base[i] {
                        Some(b) => Some(b + v),
                        None => {
                            return err(
                                w.col(c),
                                ParseErrorKind::ConflictingArguments(format!(
                                    "incremental {} while its position is unknown (G43.5 moved the rotary axes): give it in G90 first",
                                    c.to_ascii_uppercase() as char
                                )),
                            );
                        }
                    }
                };
            }
        }
        Ok(r)
    }

    /// The orientation of a move that changes nothing but X Y Z.
    fn steady_orientation(&self) -> Orientation {
        match self.tool_control {
            ToolControl::Off => Orientation::Fixed,
            ToolControl::RotaryAngles { .. } => Orientation::TcpRotary {
                start: self.rotary,
                end: self.rotary,
            },
            ToolControl::ToolVector { .. } => Orientation::TcpVector {
                start: self.tool_vector,
                end: self.tool_vector,
            },
        }
    }

    /// The orientation of a move whose rotary axes go to `end` (TCP off or
    /// G43.4); the parser's rotary state moves there.
    fn rotary_orientation(&mut self, end: Rotary) -> Orientation {
        let start = core::mem::replace(&mut self.rotary, end);
        match self.tool_control {
            ToolControl::Off if start == end => Orientation::Fixed,
            ToolControl::Off => Orientation::Axes { start, end },
            _ => Orientation::TcpRotary { start, end },
        }
    }

    /// The orientation of a G0/G1: A B C words (TCP off, G43.4) or the tool
    /// vector I J K (G43.5; I J K anywhere else is an error).
    fn move_orientation(
        &mut self,
        w: &Words,
        what: &str,
        use_word: &mut impl FnMut(u8),
    ) -> LineResult<Orientation> {
        let ijk = [b'i', b'j', b'k'];
        let given = ijk.iter().filter(|&&c| w.has(c)).map(|&c| w.col(c)).min();
        if let ToolControl::ToolVector { .. } = self.tool_control {
            let start = self.tool_vector;
            if given.is_some() {
                // Fanuc: an omitted I, J or K is 0.
                let v = ijk.map(|c| w.get(c).unwrap_or(0.0));
                if v == [0.0; 3] {
                    return err(
                        given.unwrap_or(0),
                        ParseErrorKind::BadValue("tool vector I J K is zero".into()),
                    );
                }
                ijk.into_iter().for_each(&mut *use_word);
                self.tool_vector = Some(v);
            }
            return Ok(Orientation::TcpVector {
                start,
                end: self.tool_vector,
            });
        }
        if let Some(col) = given {
            return err(
                col,
                ParseErrorKind::ConflictingArguments(format!(
                    "I/J/K on {what}: a tool vector needs G43.5 (tool-centre-point control with a tool vector)"
                )),
            );
        }
        let end = self.rotary_target(w, self.rotary)?;
        Ok(self.rotary_orientation(end))
    }

    /// Refuses A B C on a motion that has no rotary form.
    fn no_rotary_words(w: &Words, what: &str) -> LineResult<()> {
        match [b'a', b'b', b'c'].into_iter().find(|&c| w.has(c)) {
            Some(c) => err(
                w.col(c),
                ParseErrorKind::Unsupported(format!(
                    "{} on {what}, which has no rotary form (give the move as G1 or as a G6.2 curve)",
                    c.to_ascii_uppercase() as char
                )),
            ),
            None => Ok(()),
        }
    }

    /// Sets the tool-centre-point control mode; a block marks each change.
    fn set_tool_control(&mut self, mode: ToolControl, line: u32) {
        if mode == self.tool_control {
            return;
        }
        let was_vector = matches!(self.tool_control, ToolControl::ToolVector { .. });
        let is_vector = matches!(mode, ToolControl::ToolVector { .. });
        if is_vector && !was_vector {
            // The tool vector steers the rotary axes from here on: the program
            // no longer knows where they are, nor (until I J K) the vector.
            self.rotary = [None; 3];
            self.tool_vector = None;
        }
        if !is_vector {
            self.tool_vector = None;
        }
        self.tool_control = mode;
        self.push(line, BlockKind::ToolControl(mode));
    }

    fn feed(&self) -> Feed {
        if self.inverse_time {
            Feed::InverseTime(self.feed)
        } else {
            Feed::PerMinute(self.feed)
        }
    }

    fn execute(&mut self, w: &Words, line: u32) -> LineResult<bool> {
        // Modal group conflicts.
        let mut seen_g: [Option<u32>; 16] = [None; 16];
        let mut motion_code: Option<(u32, usize)> = None;
        let mut non_modal: Option<(u32, usize)> = None;
        for &(code, col) in w.gs() {
            if let Some(what) = unsupported_g(code) {
                return err(
                    col,
                    ParseErrorKind::Unsupported(format!("{} ({what})", g_name(code))),
                );
            }
            let Some((group, name)) = g_group(code) else {
                return err(col, ParseErrorKind::UnknownCode(g_name(code)));
            };
            if let Some(first) = seen_g[group as usize] {
                return err(
                    col,
                    ParseErrorKind::ModalGroupConflict {
                        group: name,
                        first: g_name(first),
                        second: g_name(code),
                    },
                );
            }
            seen_g[group as usize] = Some(code);
            if group == 1 {
                motion_code = Some((code, col));
            }
            if group == 0 {
                non_modal = Some((code, col));
            }
        }
        let mut seen_m: [Option<u32>; 16] = [None; 16];
        for &(code, col) in w.ms() {
            let Some((group, name)) = m_group(code) else {
                return err(col, ParseErrorKind::UnknownCode(format!("M{code}")));
            };
            if let Some(first) = seen_m[group as usize] {
                return err(
                    col,
                    ParseErrorKind::ModalGroupConflict {
                        group: name,
                        first: format!("M{first}"),
                        second: format!("M{code}"),
                    },
                );
            }
            seen_m[group as usize] = Some(code);
        }
        let g = |code: u32| w.gs().iter().find(|x| x.0 == code).map(|x| x.1);
        let mut used: u32 = 0;
        let mut use_word = |c: u8| used |= 1 << idx(c);

        // An open curve ends only by its own rules; another motion code inside it is an error.
        if let Some((code, col)) = motion_code {
            if self.g5.is_some() && !matches!(code, 22 | 52 | 53) {
                return err(
                    col,
                    ParseErrorKind::NurbsSequence(format!(
                        "{} inside a G5.2 curve (end it with G5.3 first)",
                        g_name(code)
                    )),
                );
            }
            if self.g6.is_some() && code != 62 {
                return err(
                    col,
                    ParseErrorKind::NurbsSequence(format!(
                        "{} inside a G6.2 curve (it ends after its last knot)",
                        g_name(code)
                    )),
                );
            }
        }

        // RS274/NGC order of execution. Units first so F on the line is in them.
        if g(200).is_some() {
            self.units = Units::Inches;
        }
        if g(210).is_some() {
            self.units = Units::Millimetres;
        }
        // LinuxCNC forgets the feed when the feed mode changes.
        for (code, inverse) in [(930, true), (940, false)] {
            if g(code).is_some() && self.inverse_time != inverse {
                self.inverse_time = inverse;
                self.feed = 0.0;
            }
        }
        if let Some(f) = w.get(b'f') {
            if f < 0.0 {
                return err(
                    w.col(b'f'),
                    ParseErrorKind::BadValue("negative feed".into()),
                );
            }
            self.feed = if self.inverse_time { f } else { self.len(f) };
        } else if self.inverse_time
            && matches!(
                motion_code.map(|m| m.0).or(self.motion_code_if_moving(w)),
                Some(10 | 20 | 30)
            )
        {
            return err(
                0,
                ParseErrorKind::MissingArgument(
                    "F word on every feed move in inverse time mode (G93)".into(),
                ),
            );
        }
        let mut spindle_changed = false;
        if let Some(s) = w.get(b's') {
            if s < 0.0 {
                return err(
                    w.col(b's'),
                    ParseErrorKind::BadValue("negative spindle speed".into()),
                );
            }
            self.speed = s;
            spindle_changed = true;
        }
        if let Some(t) = w.get(b't') {
            match near_int(t).filter(|t| (0..=i64::from(u32::MAX)).contains(t)) {
                Some(t) => self.tool = t as u32,
                None => {
                    return err(
                        w.col(b't'),
                        ParseErrorKind::BadValue(
                            "tool number T must be a non-negative integer".into(),
                        ),
                    );
                }
            }
        }
        if seen_m[6].is_some() {
            self.push(line, BlockKind::ToolChange { tool: self.tool });
        }
        if g(960).is_some() {
            self.css = true;
            spindle_changed = true;
        }
        if g(970).is_some() {
            self.css = false;
            spindle_changed = true;
        }
        if let Some(m) = seen_m[7] {
            self.rotation = match m {
                3 => SpindleRotation::Clockwise,
                4 => SpindleRotation::CounterClockwise,
                _ => SpindleRotation::Stopped,
            };
            spindle_changed = true;
        }
        if spindle_changed {
            self.push(
                line,
                BlockKind::Spindle {
                    speed: self.speed,
                    rotation: self.rotation,
                    constant_surface_speed: self.css,
                },
            );
        }
        if let Some((40, col)) = non_modal {
            {
                let Some(p) = w.get(b'p') else {
                    return err(
                        col,
                        ParseErrorKind::MissingArgument("G4 needs the dwell time P".into()),
                    );
                };
                if !(p >= 0.0) {
                    return err(
                        w.col(b'p'),
                        ParseErrorKind::BadValue("negative dwell time".into()),
                    );
                }
                use_word(b'p');
                self.push(line, BlockKind::Dwell { seconds: p });
            }
        }
        if let Some(code) = seen_g[2] {
            let plane = match code {
                170 => Plane::Xy,
                180 => Plane::Zx,
                _ => Plane::Yz,
            };
            if (self.g5.is_some() || self.g6.is_some()) && plane != self.plane {
                return err(
                    g(code).unwrap_or(0),
                    ParseErrorKind::NurbsSequence("plane change inside a NURBS curve".into()),
                );
            }
            self.plane = plane;
        }
        if let Some(code) = seen_g[8] {
            let col = g(code).unwrap_or(0);
            if self.g5.is_some() || self.g6.is_some() {
                return err(
                    col,
                    ParseErrorKind::NurbsSequence(format!(
                        "{} inside a NURBS curve (tool-centre-point control changes between moves)",
                        g_name(code)
                    )),
                );
            }
            let offset = match w.get(b'h') {
                Some(h) if code != 490 => {
                    use_word(b'h');
                    match near_int(h).filter(|h| (0..=i64::from(u32::MAX)).contains(h)) {
                        Some(h) => Some(h as u32),
                        None => {
                            return err(
                                w.col(b'h'),
                                ParseErrorKind::BadValue(
                                    "tool length offset H must be a non-negative integer".into(),
                                ),
                            );
                        }
                    }
                }
                _ => None,
            };
            let mode = match code {
                434 => ToolControl::RotaryAngles { offset },
                435 => ToolControl::ToolVector { offset },
                _ => ToolControl::Off,
            };
            self.set_tool_control(mode, line);
        }
        if let Some(code) = seen_g[13] {
            let pc = match code {
                610 => PathControl::ExactPath,
                611 => PathControl::ExactStop,
                _ => {
                    let p = w.get(b'p');
                    let q = w.get(b'q');
                    for (c, v) in [(b'p', p), (b'q', q)] {
                        if let Some(v) = v {
                            if v < 0.0 {
                                return err(
                                    w.col(c),
                                    ParseErrorKind::BadValue("negative G64 tolerance".into()),
                                );
                            }
                            use_word(c);
                        }
                    }
                    if q.is_some() && p.is_none() {
                        return err(
                            w.col(b'q'),
                            ParseErrorKind::MissingArgument("G64 Q needs P".into()),
                        );
                    }
                    PathControl::Blend {
                        path_tolerance: p.map(|v| self.len(v)),
                        naive_cam_tolerance: q.map(|v| self.len(v)),
                    }
                }
            };
            self.push(line, BlockKind::PathControl(pc));
        }
        if g(900).is_some() {
            self.absolute = true;
        }
        if g(910).is_some() {
            self.absolute = false;
        }
        if g(901).is_some() {
            self.arc_absolute = true;
        }
        if g(911).is_some() {
            self.arc_absolute = false;
        }

        // Motion.
        if let Some((code, _)) = motion_code {
            self.motion = match code {
                0 => Some(Motion::Rapid),
                10 => Some(Motion::Linear),
                20 => Some(Motion::ArcCw),
                30 => Some(Motion::ArcCcw),
                50 => Some(Motion::Cubic),
                51 => Some(Motion::Quadratic),
                // G2.2 is not a LinuxCNC code, but one corpus program (LinuxCNC's
                // own `Curva_Stella #1=1_G5.ngc`) opens a G5.2 curve with it and
                // closes it with G5.3: read it as G5.2.
                52 | 22 => Some(Motion::G5_2),
                62 => Some(Motion::G6_2),
                _ => self.motion, // G5.3, G80 handled below
            };
        }
        let rotary_words = w.has(b'a') || w.has(b'b') || w.has(b'c');
        let axes = w.has(b'x') || w.has(b'y') || w.has(b'z') || rotary_words;
        // Under G43.5 a G0/G1 may turn the tool alone (I J K only).
        let vector_words = self.vector_words(w);
        if rotary_words && matches!(self.tool_control, ToolControl::ToolVector { .. }) {
            return err(
                w.col(b'a').max(w.col(b'b')).max(w.col(b'c')),
                ParseErrorKind::ConflictingArguments(
                    "A/B/C under G43.5: the tool vector I J K steers the rotary axes (G43.4 takes A B C)"
                        .into(),
                ),
            );
        }
        match motion_code.map(|m| m.0) {
            Some(53) => {
                let col = motion_code.map_or(0, |m| m.1);
                self.end_g5(line, col)?;
            }
            Some(800) => {
                if axes {
                    return err(
                        AXIS_WORDS.into_iter().map(|c| w.col(c)).max().unwrap_or(0),
                        ParseErrorKind::ConflictingArguments("axis words with G80".into()),
                    );
                }
                self.motion = None;
            }
            _ => {
                let explicit = motion_code.is_some();
                let kval = w.has(b'k');
                match self.motion {
                    None if axes => {
                        return err(
                            AXIS_WORDS
                                .into_iter()
                                .filter(|&c| w.has(c))
                                .map(|c| w.col(c))
                                .min()
                                .unwrap_or(0),
                            ParseErrorKind::MissingArgument(
                                "a motion mode for the axis words (none is active)".into(),
                            ),
                        );
                    }
                    // LinuxCNC moves (by zero) on an explicit G0/G1 without axis words.
                    Some(Motion::Rapid) if axes || explicit || vector_words => {
                        let end = self.target(w, self.pos);
                        let orientation = self.move_orientation(w, "G0", &mut use_word)?;
                        self.push(
                            line,
                            BlockKind::Rapid(RapidMove {
                                start: self.pos,
                                end,
                                orientation,
                            }),
                        );
                        self.pos = end;
                    }
                    Some(Motion::Linear) if axes || explicit || vector_words => {
                        self.check_feed(w, motion_code.map_or(0, |m| m.1), "G1")?;
                        let end = self.target(w, self.pos);
                        let orientation = self.move_orientation(w, "G1", &mut use_word)?;
                        self.push(
                            line,
                            BlockKind::Linear(LinearMove {
                                start: self.pos,
                                end,
                                feed: self.feed(),
                                orientation,
                            }),
                        );
                        self.pos = end;
                    }
                    Some(m @ (Motion::ArcCw | Motion::ArcCcw)) if axes || explicit => {
                        let col = motion_code.map_or(w.col(b'x'), |m| m.1);
                        self.check_feed(w, col, "G2/G3")?;
                        self.arc(w, line, col, m == Motion::ArcCw, &mut use_word)?;
                    }
                    Some(m @ (Motion::Cubic | Motion::Quadratic)) if axes || explicit => {
                        let col = motion_code.map_or(w.col(b'x'), |m| m.1);
                        self.check_feed(w, col, "G5/G5.1")?;
                        self.bezier(w, line, col, m == Motion::Cubic, &mut use_word)?;
                    }
                    Some(Motion::G5_2)
                        if axes || explicit || (self.g5.is_some() && w.has(b'p')) =>
                    {
                        let col = motion_code.map_or(w.col(b'x'), |m| m.1);
                        self.g5_point(w, line, col, explicit, &mut use_word)?;
                    }
                    Some(Motion::G6_2) if axes || explicit || (self.g6.is_some() && kval) => {
                        let col = motion_code.map_or(w.col(b'k'), |m| m.1);
                        self.g6_point(w, line, col, &mut use_word)?;
                    }
                    _ => {}
                }
                if !matches!(self.motion, Some(Motion::Cubic)) {
                    self.last_cubic_pq = None;
                }
            }
        }

        // Words nothing used.
        for c in [b'u', b'v', b'w'] {
            if w.has(c) && used & (1 << idx(c)) == 0 {
                return err(
                    w.col(c),
                    ParseErrorKind::Unsupported(format!(
                        "axis word '{}' (interpd has X Y Z A B C; U V W are only the tool vector on G6.2 control points under G43.5)",
                        c.to_ascii_uppercase() as char
                    )),
                );
            }
        }
        for c in [b'd', b'h', b'i', b'j', b'k', b'l', b'p', b'q', b'r'] {
            if w.has(c) && used & (1 << idx(c)) == 0 {
                return err(
                    w.col(c),
                    ParseErrorKind::ConflictingArguments(format!(
                        "{} word with no command on the line that uses it",
                        c.to_ascii_uppercase() as char
                    )),
                );
            }
        }

        if let Some(2 | 30) = seen_m[4] {
            {
                if let Some(c) = &self.g5 {
                    return err(
                        0,
                        ParseErrorKind::NurbsSequence(format!(
                            "program ends inside the G5.2 curve of line {}",
                            c.first_line
                        )),
                    );
                }
                if let Some(c) = &self.g6 {
                    return err(
                        0,
                        ParseErrorKind::NurbsSequence(format!(
                            "program ends inside the G6.2 curve of line {}",
                            c.first_line
                        )),
                    );
                }
                self.push(line, BlockKind::ProgramEnd);
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// I J K on a line under G43.5 (a tool vector for G0/G1).
    fn vector_words(&self, w: &Words) -> bool {
        matches!(self.tool_control, ToolControl::ToolVector { .. })
            && (w.has(b'i') || w.has(b'j') || w.has(b'k'))
    }

    /// The motion code a line without one will run (for the G93 F check).
    fn motion_code_if_moving(&self, w: &Words) -> Option<u32> {
        let axes = AXIS_WORDS.into_iter().any(|c| w.has(c));
        let vector = self.vector_words(w) && matches!(self.motion, Some(Motion::Linear));
        if !(axes || vector) {
            return None;
        }
        Some(match self.motion? {
            Motion::Rapid => 0,
            Motion::Linear => 10,
            Motion::ArcCw => 20,
            Motion::ArcCcw => 30,
            Motion::Cubic => 50,
            Motion::Quadratic => 51,
            Motion::G5_2 | Motion::G6_2 => return None,
        })
    }

    fn check_feed(&self, w: &Words, col: usize, what: &str) -> LineResult<()> {
        let _ = w;
        if !self.inverse_time && self.feed == 0.0 {
            return err(
                col,
                ParseErrorKind::MissingArgument(format!("a non-zero feed F for {what}")),
            );
        }
        Ok(())
    }

    fn arc(
        &mut self,
        w: &Words,
        line: u32,
        col: usize,
        clockwise: bool,
        use_word: &mut impl FnMut(u8),
    ) -> LineResult<()> {
        Self::no_rotary_words(w, if clockwise { "G2" } else { "G3" })?;
        let plane = self.plane;
        let (a, b, n) = plane.axes();
        let offs = [b'i', b'j', b'k'];
        let start = self.pos;
        let end = self.target(w, self.pos);
        if w.has(offs[n]) {
            return err(
                w.col(offs[n]),
                ParseErrorKind::ConflictingArguments(format!(
                    "{} word for an arc in the G{} plane",
                    offs[n].to_ascii_uppercase() as char,
                    plane.g_code()
                )),
            );
        }
        let turns = match w.get(b'p') {
            None => 1,
            Some(p) => {
                use_word(b'p');
                match near_int(p).filter(|&t| t >= 1 && t <= i64::from(u32::MAX)) {
                    Some(t) => t as u32,
                    None => {
                        return err(
                            w.col(b'p'),
                            ParseErrorKind::BadValue(
                                "arc turns P must be a positive integer".into(),
                            ),
                        );
                    }
                }
            }
        };
        let (rad_tol, spiral_abs) = match self.units {
            Units::Millimetres => (
                RADIUS_TOLERANCE_INCH * Units::MM_PER_INCH,
                CENTER_ARC_RADIUS_TOLERANCE_MM,
            ),
            Units::Inches => (
                RADIUS_TOLERANCE_INCH * Units::MM_PER_INCH,
                CENTER_ARC_RADIUS_TOLERANCE_INCH * Units::MM_PER_INCH,
            ),
        };
        let (sx, sy, ex, ey) = (start[a], start[b], end[a], end[b]);
        let (cx, cy);
        if let Some(r) = w.get(b'r') {
            use_word(b'r');
            if w.has(offs[a]) || w.has(offs[b]) {
                return err(
                    w.col(b'r'),
                    ParseErrorKind::ConflictingArguments("arc with both R and I/J/K".into()),
                );
            }
            let r = self.len(r);
            if ex == sx && ey == sy {
                return err(
                    col,
                    ParseErrorKind::BadArc(
                        "radius-format arc whose end is its start (a full circle needs I/J/K)"
                            .into(),
                    ),
                );
            }
            let abs_r = r.abs();
            let (mx, my) = ((ex + sx) / 2.0, (ey + sy) / 2.0);
            let mut half = (mx - ex).hypot(my - ey);
            if half - abs_r > rad_tol {
                return err(
                    w.col(b'r'),
                    ParseErrorKind::BadArc(format!(
                        "radius {abs_r} mm is too small to reach the end point"
                    )),
                );
            }
            if half / abs_r > 1.0 - ARC_R_TINY {
                half = abs_r;
            }
            let base = (ey - sy).atan2(ex - sx);
            let theta = if clockwise == (r > 0.0) {
                base - core::f64::consts::FRAC_PI_2
            } else {
                base + core::f64::consts::FRAC_PI_2
            };
            let turn2 = (half / abs_r).asin();
            let offset = abs_r * turn2.cos();
            cx = mx + offset * theta.cos();
            cy = my + offset * theta.sin();
        } else {
            if !w.has(offs[a]) && !w.has(offs[b]) {
                return err(
                    col,
                    ParseErrorKind::MissingArgument(format!(
                        "{} or {} (or R) for the arc",
                        offs[a].to_ascii_uppercase() as char,
                        offs[b].to_ascii_uppercase() as char
                    )),
                );
            }
            use_word(offs[a]);
            use_word(offs[b]);
            let i = self.len(w.get(offs[a]).unwrap_or(0.0));
            let j = self.len(w.get(offs[b]).unwrap_or(0.0));
            (cx, cy) = if self.arc_absolute {
                (i, j)
            } else {
                (sx + i, sy + j)
            };
            let r1 = (cx - sx).hypot(cy - sy);
            let r2 = (cx - ex).hypot(cy - ey);
            if r1 < rad_tol || r2 < rad_tol {
                return err(
                    col,
                    ParseErrorKind::BadArc(format!(
                        "zero radius (start radius {r1} mm, end radius {r2} mm)"
                    )),
                );
            }
            let abs_err = (r1 - r2).abs();
            let rel_err = abs_err / r1.max(r2);
            if abs_err > spiral_abs * SPIRAL_ABS_HARD_FACTOR
                || (rel_err > SPIRAL_RELATIVE_TOLERANCE && abs_err > spiral_abs)
            {
                return err(
                    col,
                    ParseErrorKind::BadArc(format!(
                        "radius to end of arc {r2} mm differs from radius to start {r1} mm"
                    )),
                );
            }
        }
        let mut centre = start;
        centre[a] = cx;
        centre[b] = cy;
        if !(cx.is_finite() && cy.is_finite()) {
            return err(col, ParseErrorKind::BadArc("centre is not finite".into()));
        }
        self.push(
            line,
            BlockKind::Arc(ArcMove {
                start,
                end,
                centre,
                plane,
                clockwise,
                extra_turns: turns - 1,
                feed: self.feed(),
                orientation: self.steady_orientation(),
            }),
        );
        self.pos = end;
        Ok(())
    }

    /// G5 (cubic) and G5.1 (quadratic) Béziers, XY plane only (as LinuxCNC).
    fn bezier(
        &mut self,
        w: &Words,
        line: u32,
        col: usize,
        cubic: bool,
        use_word: &mut impl FnMut(u8),
    ) -> LineResult<()> {
        let name = if cubic { "G5" } else { "G5.1" };
        Self::no_rotary_words(w, name)?;
        if self.plane != Plane::Xy {
            return err(
                col,
                ParseErrorKind::Unsupported(format!("{name} outside the XY plane (G17)")),
            );
        }
        if w.has(b'z') {
            return err(
                w.col(b'z'),
                ParseErrorKind::Unsupported(format!("Z on {name} (the spline is planar)")),
            );
        }
        if !w.has(b'x') && !w.has(b'y') && !cubic {
            return err(
                col,
                ParseErrorKind::MissingArgument(format!("X or Y for {name}")),
            );
        }
        let start = self.pos;
        let end = self.target(w, self.pos);
        let has_ij = w.has(b'i') || w.has(b'j');
        let ij = |s: &Self| {
            [
                s.len(w.get(b'i').unwrap_or(0.0)),
                s.len(w.get(b'j').unwrap_or(0.0)),
            ]
        };
        let points: Vec<Point> = if cubic {
            let first = if has_ij {
                use_word(b'i');
                use_word(b'j');
                ij(self)
            } else if let Some(pq) = self.last_cubic_pq {
                [-pq[0], -pq[1]]
            } else {
                return err(
                    col,
                    ParseErrorKind::MissingArgument(
                        "I and J on a G5 that does not follow a G5".into(),
                    ),
                );
            };
            if !(w.has(b'p') && w.has(b'q')) {
                return err(col, ParseErrorKind::MissingArgument("P and Q on G5".into()));
            }
            use_word(b'p');
            use_word(b'q');
            let pq = [self.len(w.values[idx(b'p')]), self.len(w.values[idx(b'q')])];
            self.last_cubic_pq = Some(pq);
            vec![
                start,
                [start[0] + first[0], start[1] + first[1], start[2]],
                [end[0] + pq[0], end[1] + pq[1], start[2]],
                end,
            ]
        } else {
            if !(w.has(b'i') && w.has(b'j')) {
                return err(
                    col,
                    ParseErrorKind::MissingArgument("I and J on G5.1".into()),
                );
            }
            use_word(b'i');
            use_word(b'j');
            let c = ij(self);
            vec![start, [start[0] + c[0], start[1] + c[1], start[2]], end]
        };
        let degree = points.len() - 1;
        let mut knots = vec![0.0; degree + 1];
        knots.extend(std::iter::repeat_n(1.0, degree + 1));
        let weights = vec![1.0; points.len()];
        let rotary = vec![self.rotary; points.len()];
        self.push_nurbs(
            line,
            col,
            line,
            degree,
            points,
            weights,
            knots,
            rotary,
            Vec::new(),
            &[],
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn push_nurbs(
        &mut self,
        line: u32,
        col: usize,
        first_line: u32,
        degree: usize,
        points: Vec<Point>,
        weights: Vec<f64>,
        knots: Vec<f64>,
        rotary: Vec<Rotary>,
        vectors: Vec<[f64; 3]>,
        sources: &[(u32, usize)],
    ) -> LineResult<()> {
        match validate_program_curve(degree, &points, &weights, &knots) {
            // A curve that stops (e.g. a repeated first control point, common in
            // LinuxCNC's G5.2 examples) is still a valid program; whether the
            // interpolator can run it is the conversion's question.
            Ok(()) | Err(NurbsError::ZeroSpeed { .. }) => {}
            Err(e) => {
                let index = match e {
                    NurbsError::DecreasingKnot { index }
                    | NurbsError::KnotMultiplicity { index }
                    | NurbsError::NonPositiveWeight { index }
                    | NurbsError::NonFinite { index, .. } => Some(index),
                    _ => None,
                };
                let (l, c) = index
                    .and_then(|i| sources.get(i).copied())
                    .unwrap_or((first_line, col));
                if l != line {
                    self.error_line = Some(l);
                }
                return err(c, ParseErrorKind::InvalidNurbs(e));
            }
        }
        let start = points[0];
        let (first_rotary, last_rotary) = match (rotary.first(), rotary.last()) {
            (Some(f), Some(l)) => (*f, *l),
            _ => (self.rotary, self.rotary),
        };
        let first_vector = vectors.first().copied().or(self.tool_vector);
        if start != self.pos || first_rotary != self.rotary || first_vector != self.tool_vector {
            // LinuxCNC feeds in a straight line to the curve's first point
            // (turning the tool to the curve's first vector on the way).
            let orientation = match self.tool_control {
                ToolControl::ToolVector { .. } => Orientation::TcpVector {
                    start: core::mem::replace(&mut self.tool_vector, first_vector),
                    end: first_vector,
                },
                _ => self.rotary_orientation(first_rotary),
            };
            self.push(
                line,
                BlockKind::Linear(LinearMove {
                    start: self.pos,
                    end: start,
                    feed: self.feed(),
                    orientation,
                }),
            );
        }
        self.pos = points[points.len() - 1];
        let (orientation, rotary) = match self.tool_control {
            ToolControl::ToolVector { .. } if !vectors.is_empty() => {
                self.tool_vector = vectors.last().copied();
                (
                    Orientation::TcpVector {
                        start: first_vector,
                        end: self.tool_vector,
                    },
                    Vec::new(),
                )
            }
            ToolControl::ToolVector { .. } => (self.steady_orientation(), Vec::new()),
            ToolControl::Off if rotary.iter().all(|r| *r == first_rotary) => {
                (Orientation::Fixed, Vec::new())
            }
            ToolControl::Off => (
                Orientation::Axes {
                    start: first_rotary,
                    end: last_rotary,
                },
                rotary,
            ),
            ToolControl::RotaryAngles { .. } => (
                Orientation::TcpRotary {
                    start: first_rotary,
                    end: last_rotary,
                },
                rotary,
            ),
        };
        if !matches!(self.tool_control, ToolControl::ToolVector { .. }) {
            self.rotary = last_rotary;
        }
        let plane = self.plane;
        let feed = self.feed();
        self.push(
            line,
            BlockKind::Nurbs(NurbsMove {
                first_line,
                plane,
                degree,
                points,
                weights,
                knots,
                feed,
                orientation,
                rotary,
                tool_vectors: vectors,
            }),
        );
        Ok(())
    }

    fn plane_pair(&self, w: &Words, col: usize) -> LineResult<bool> {
        let (a, b, _) = self.plane.axes();
        let l = [b'x', b'y', b'z'];
        match (w.has(l[a]), w.has(l[b])) {
            (true, true) => Ok(true),
            (false, false) => Ok(false),
            _ => err(
                col,
                ParseErrorKind::MissingArgument(format!(
                    "both {} and {} for a control point",
                    l[a].to_ascii_uppercase() as char,
                    l[b].to_ascii_uppercase() as char
                )),
            ),
        }
    }

    fn g5_point(
        &mut self,
        w: &Words,
        line: u32,
        col: usize,
        explicit: bool,
        use_word: &mut impl FnMut(u8),
    ) -> LineResult<()> {
        Self::no_rotary_words(w, "G5.2")?;
        let has_pair = self.plane_pair(w, col)?;
        if !self.inverse_time && self.feed == 0.0 {
            return err(
                col,
                ParseErrorKind::MissingArgument("a non-zero feed F for a NURBS".into()),
            );
        }
        let p = w.get(b'p');
        if p.is_some() {
            use_word(b'p');
        }
        if self.g5.is_none() {
            let _ = explicit;
            let w0 = match p {
                Some(p) if !has_pair && p > 0.0 => p,
                _ => 1.0,
            };
            self.g5 = Some(G5Curve {
                first_line: line,
                plane: self.plane,
                order: G5_2_DEFAULT_ORDER,
                start: self.pos,
                points: vec![self.pos],
                weights: vec![w0],
                sources: vec![(line, col)],
            });
        } else if !has_pair && p.is_some() {
            return err(
                w.col(b'p'),
                ParseErrorKind::ConflictingArguments(
                    "P without the control point's coordinates (only the first G5.2 line may)"
                        .into(),
                ),
            );
        }
        if let Some(l) = w.get(b'l') {
            use_word(b'l');
            let Some(l) = near_int(l) else {
                return err(
                    w.col(b'l'),
                    ParseErrorKind::BadValue("order L must be an integer".into()),
                );
            };
            if let Some(c) = self.g5.as_mut().filter(|_| l > G5_2_DEFAULT_ORDER as i64) {
                c.order = usize::try_from(l).unwrap_or(usize::MAX);
            }
        }
        if has_pair {
            let Some(p) = p.filter(|p| *p > 0.0) else {
                return err(
                    if w.has(b'p') { w.col(b'p') } else { col },
                    ParseErrorKind::BadValue(
                        "a positive weight P on every G5.2 control point".into(),
                    ),
                );
            };
            let base = self.g5.as_ref().map_or(self.pos, |c| c.start);
            let pt = self.target(w, base);
            if let Some(c) = self.g5.as_mut() {
                c.points.push(pt);
                c.weights.push(p);
                c.sources.push((line, col));
            }
        }
        Ok(())
    }

    fn end_g5(&mut self, line: u32, col: usize) -> LineResult<()> {
        let Some(c) = self.g5.take() else {
            return err(
                col,
                ParseErrorKind::NurbsSequence("G5.3 without G5.2 first".into()),
            );
        };
        if c.points.len() < c.order {
            return err(
                col,
                ParseErrorKind::NurbsSequence(format!(
                    "{} control points, fewer than the order L = {}",
                    c.points.len(),
                    c.order
                )),
            );
        }
        let knots = g5_2_knots(c.points.len(), c.order);
        self.motion = None;
        self.plane = c.plane;
        let rotary = vec![self.rotary; c.points.len()];
        self.push_nurbs(
            line,
            col,
            c.first_line,
            c.order - 1,
            c.points,
            c.weights,
            knots,
            rotary,
            Vec::new(),
            &c.sources,
        )
    }

    /// The tool vector `U V W` of a G6.2 line (G43.5 only; an omitted
    /// component is 0, as Fanuc's I J K; absolute whatever G90/G91 say):
    /// given on every control point line of a curve or on none. A line
    /// without a control point has none (a first point without
    /// coordinates takes the current vector).
    fn g6_vector(
        &mut self,
        w: &Words,
        line: u32,
        col: usize,
        has_pair: bool,
        use_word: &mut impl FnMut(u8),
    ) -> LineResult<Option<[f64; 3]>> {
        let uvw = [b'u', b'v', b'w'];
        let given = uvw.iter().filter(|&&c| w.has(c)).map(|&c| w.col(c)).min();
        let letters = "U V W";
        if let Some(at) = given {
            if !matches!(self.tool_control, ToolControl::ToolVector { .. }) {
                return err(
                    at,
                    ParseErrorKind::ConflictingArguments(format!(
                        "{letters} (a tool vector) on a G6.2 line outside G43.5"
                    )),
                );
            }
            if !has_pair {
                return err(
                    at,
                    ParseErrorKind::ConflictingArguments(format!(
                        "{letters} on a G6.2 line without a control point"
                    )),
                );
            }
        }
        let Some(c) = self.g6.as_mut() else {
            return Ok(None);
        };
        if !has_pair {
            return Ok(self.tool_vector);
        }
        match c.vectors_given {
            None => c.vectors_given = Some((given.is_some(), line)),
            Some((true, first)) if given.is_none() => {
                return err(
                    col,
                    ParseErrorKind::MissingArgument(format!(
                        "the tool vector {letters} on this control point: the curve's point on line {first} gives one, so every point needs one"
                    )),
                );
            }
            Some((false, first)) if given.is_some() => {
                return err(
                    given.unwrap_or(col),
                    ParseErrorKind::ConflictingArguments(format!(
                        "{letters} on this control point but not on the curve's point on line {first}: give the tool vector on every point or on none"
                    )),
                );
            }
            _ => {}
        }
        let Some(at) = given else {
            return Ok(None);
        };
        let v = uvw.map(|c| w.get(c).unwrap_or(0.0));
        if v == [0.0; 3] {
            return err(
                at,
                ParseErrorKind::BadValue(format!("tool vector {letters} is zero")),
            );
        }
        uvw.into_iter().for_each(&mut *use_word);
        Ok(Some(v))
    }

    fn g6_point(
        &mut self,
        w: &Words,
        line: u32,
        col: usize,
        use_word: &mut impl FnMut(u8),
    ) -> LineResult<()> {
        let has_pair = self.plane_pair(w, col)?;
        if !self.inverse_time && self.feed == 0.0 {
            return err(
                col,
                ParseErrorKind::MissingArgument("a non-zero feed F for a NURBS".into()),
            );
        }
        let first = self.g6.is_none();
        if let Some(p) = w.get(b'p') {
            use_word(b'p');
            let Some(order) = near_int(p).filter(|o| (2..=64).contains(o)) else {
                return err(
                    w.col(b'p'),
                    ParseErrorKind::BadValue("NURBS order P must be an integer in 2..=64".into()),
                );
            };
            if let Some(c) = self.g6.as_mut() {
                c.order = order as usize;
            } else {
                self.g6 = Some(G6Curve {
                    first_line: line,
                    first_col: col,
                    order: order as usize,
                    start: self.pos,
                    points: Vec::new(),
                    weights: Vec::new(),
                    knots: Vec::new(),
                    sources: Vec::new(),
                    rotary: Vec::new(),
                    vectors: Vec::new(),
                    vectors_given: None,
                });
            }
        } else if first {
            return err(
                col,
                ParseErrorKind::MissingArgument("the NURBS order P on the first G6.2 line".into()),
            );
        }
        // Q is LinuxCNC's choice of how to approximate the curve (1, 2 or 3);
        // Fanuc's G06.2 has none. The curve is exact here either way.
        if let Some(q) = w.get(b'q') {
            use_word(b'q');
            if !matches!(near_int(q), Some(1..=3)) {
                return err(
                    w.col(b'q'),
                    ParseErrorKind::BadValue("NURBS Q must be 1, 2 or 3".into()),
                );
            }
        }
        let Some(k) = w.get(b'k') else {
            return err(
                col,
                ParseErrorKind::MissingArgument("knot K on every G6.2 line".into()),
            );
        };
        use_word(b'k');
        let r = w.get(b'r');
        if r.is_some() {
            use_word(b'r');
        }
        let Some(c) = self.g6.as_ref() else {
            return err(
                col,
                ParseErrorKind::NurbsSequence("G6.2 curve was not started".into()),
            );
        };
        let base = c.start;
        let base_rotary = self.rotary;
        let rotary_words = [b'a', b'b', b'c'].into_iter().find(|&l| w.has(l));
        let rotary = match rotary_words {
            Some(l) if !has_pair => {
                return err(
                    w.col(l),
                    ParseErrorKind::ConflictingArguments(format!(
                        "{} on a G6.2 line without a control point",
                        l.to_ascii_uppercase() as char
                    )),
                );
            }
            Some(_) => self.rotary_target(w, base_rotary)?,
            None => base_rotary,
        };
        // Each rotary axis is a coordinate of every control point or of none.
        if let Some(prev) = c.rotary.first() {
            for (i, l) in [b'a', b'b', b'c'].into_iter().enumerate() {
                if prev[i].is_some() != rotary[i].is_some() && has_pair {
                    return err(
                        if w.has(l) { w.col(l) } else { col },
                        ParseErrorKind::ConflictingArguments(format!(
                            "{} is not known on every control point of this G6.2 curve (its position is unknown after G43.5): give it on every point",
                            l.to_ascii_uppercase() as char
                        )),
                    );
                }
            }
        }
        let vector = self.g6_vector(w, line, col, has_pair, use_word)?;
        let point = if has_pair {
            match r {
                Some(r) if r > 0.0 => {}
                _ => {
                    return err(
                        if w.has(b'r') { w.col(b'r') } else { col },
                        ParseErrorKind::BadValue(
                            "a positive weight R on every G6.2 control point".into(),
                        ),
                    );
                }
            }
            self.target(w, base)
        } else {
            base
        };
        let Some(c) = self.g6.as_mut() else {
            return Ok(());
        };
        c.points.push(point);
        c.weights.push(r.unwrap_or(1.0));
        c.knots.push(k);
        c.sources.push((line, col));
        c.rotary.push(rotary);
        c.vectors.push(vector);
        let n = c.knots.len();
        // LinuxCNC ends the curve once the last `order` knots are equal.
        if n > c.order && c.knots[n - 1] == c.knots[n - c.order] {
            let Some(mut c) = self.g6.take() else {
                return Ok(());
            };
            let count = n - c.order;
            c.points.truncate(count);
            c.weights.truncate(count);
            c.rotary.truncate(count);
            c.vectors.truncate(count);
            self.motion = None;
            let col = c.first_col;
            if count == 0 {
                return err(
                    col,
                    ParseErrorKind::NurbsSequence("G6.2 curve without control points".into()),
                );
            }
            let vectors = match c.vectors_given {
                Some((true, _)) => {
                    let mut vs = Vec::with_capacity(count);
                    for (v, &(l, col)) in c.vectors.iter().zip(&c.sources) {
                        let Some(v) = v else {
                            // (Only a first point without coordinates.)
                            if l != line {
                                self.error_line = Some(l);
                            }
                            return err(
                                col,
                                ParseErrorKind::MissingArgument(
                                    "the tool vector U V W of the curve's first point (no tool vector is known here: give its X Y Z and U V W)".into(),
                                ),
                            );
                        };
                        vs.push(*v);
                    }
                    vs
                }
                _ => Vec::new(),
            };
            self.push_nurbs(
                line,
                col,
                c.first_line,
                c.order - 1,
                c.points,
                c.weights,
                c.knots,
                c.rotary,
                vectors,
                &c.sources,
            )?;
        }
        Ok(())
    }
}

/// LinuxCNC's G5.2 knot vector for `count` control points of order `order`:
/// `order` zeros, then 1, 2, … up to `count − order + 1` repeated `order` times
/// (clamped, uniform).
pub fn g5_2_knots(count: usize, order: usize) -> Vec<f64> {
    let n = count.saturating_sub(1);
    (0..=n + order)
        .map(|i| {
            if i < order {
                0.0
            } else if i <= n {
                (i + 1 - order) as f64
            } else {
                (n + 2 - order) as f64
            }
        })
        .collect()
}
