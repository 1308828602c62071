//! Recorded spatula trajectories: a time-stamped pose track per spatula, in a
//! documented, human-readable CSV.
//!
//! Format (UTF-8 text, one sample per row):
//! ```text
//! # any line starting with '#' is a comment; blank lines are ignored
//! time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz
//! 0.0,0,10.0,-5.0,40.0,1.0,0.0,0.0,0.0
//! ```
//! `time_s`: seconds; `spatula`: index into the scenario's `spatulas` list
//! (0..256); `x_mm,y_mm,z_mm`: origin of the spatula frame in millimetres;
//! `qw,qx,qy,qz`: its orientation, a unit quaternion (norm within 1e-4 of 1).
//! Rows of different spatulas may interleave; each spatula's times strictly increase.
//! An optional tenth column, `cut` (header `...,qz,cut`), is 1 on a row where the
//! trainee cuts with microscissors at that blade's tip (the arachnoid bands
//! within 2 mm of it) and 0 elsewhere.
//!
//! In: such a file, or poses as they happen ([`TrajectoryRecorder`]). Out: a
//! [`Trajectory`] that samples a [`Pose`] at any time (linear position, slerp
//! rotation, clamped outside the recorded range). Stays true: every stored
//! number is finite, every quaternion unit within 1e-4, times strictly
//! increase per spatula; `save` then `load` gives back identical numbers (f64
//! written in shortest round-trip form); parsing never panics.

use std::fmt::Write as _;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use crate::geometry::Pose;
use crate::math::{Quat, Vec3};

/// The header row every trajectory file has.
pub const HEADER: &str = "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz";
/// The header of a trajectory with the `cut` column.
pub const HEADER_WITH_CUT: &str = "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz,cut";

/// Spatula indices a trajectory accepts: 0..MAX_SPATULAS.
pub const MAX_SPATULAS: usize = 256;

/// Tolerance on |q| - 1 for a quaternion to count as unit.
pub const UNIT_TOLERANCE: f64 = 1e-4;

/// Errors reading, building or writing a trajectory.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// File system error.
    #[error("{}: {io}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error (shown in the message, so not repeated as a cause).
        io: std::io::Error,
    },
    /// Not a regular file, or over [`crate::fsio::Cap::TRAJECTORY`]; nothing was read.
    #[error("{}: {refusal}", path.display())]
    Refused {
        /// The file.
        path: PathBuf,
        /// Why.
        refusal: crate::fsio::Refusal,
    },
    /// A malformed or invalid row (line is 1-based).
    #[error("{}:{line}: {problem}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: String,
    },
    /// An invalid sample handed to [`Trajectory::push`] or [`TrajectoryRecorder::record`].
    #[error("trajectory sample for spatula {spatula} at {time_s} s: {problem}")]
    Sample {
        /// Spatula index.
        spatula: usize,
        /// Sample time, s.
        time_s: f64,
        /// What is wrong.
        problem: String,
    },
}

/// One recorded pose, as written in the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time, s (finite).
    pub time_s: f64,
    /// Origin of the spatula frame, mm (finite).
    pub position_mm: [f64; 3],
    /// Orientation (w, x, y, z), unit within [`UNIT_TOLERANCE`].
    pub quaternion: [f64; 4],
}

impl Sample {
    /// The sample of a pose (metres -> millimetres).
    pub fn from_pose(time_s: f64, pose: &Pose) -> Self {
        let q = pose.rotation.quaternion();
        let p = pose.position * 1e3;
        Sample { time_s, position_mm: [p.x, p.y, p.z], quaternion: [q.w, q.i, q.j, q.k] }
    }

    fn check(&self) -> Result<(), String> {
        if !self.time_s.is_finite() {
            return Err(format!("time_s must be finite, got {}", self.time_s));
        }
        if !self.position_mm.iter().all(|c| c.is_finite()) {
            return Err(format!("position must be finite, got {:?}", self.position_mm));
        }
        if !self.quaternion.iter().all(|c| c.is_finite()) {
            return Err(format!("quaternion must be finite, got {:?}", self.quaternion));
        }
        let norm = self.quaternion.iter().map(|c| c * c).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > UNIT_TOLERANCE {
            return Err(format!("quaternion must be unit (norm within {UNIT_TOLERANCE} of 1), its norm is {norm}"));
        }
        Ok(())
    }
}

/// Pose tracks, one per spatula index (an index without rows has an empty track).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    tracks: Vec<Vec<Sample>>,
    /// Per spatula, the times of its rows with `cut` = 1, increasing.
    cuts: Vec<Vec<f64>>,
}

impl Trajectory {
    /// An empty trajectory.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a sample to a spatula's track: finite, unit quaternion, time after the track's last.
    pub fn push(&mut self, spatula: usize, sample: Sample) -> Result<(), TrajectoryError> {
        let bad = |problem: String| TrajectoryError::Sample { spatula, time_s: sample.time_s, problem };
        if spatula >= MAX_SPATULAS {
            return Err(bad(format!("spatula index must be below {MAX_SPATULAS}")));
        }
        sample.check().map_err(bad)?;
        if self.tracks.len() <= spatula {
            self.tracks.resize_with(spatula + 1, Vec::new);
        }
        if let Some(last) = self.tracks[spatula].last()
            && sample.time_s <= last.time_s
        {
            return Err(bad(format!("times must strictly increase per spatula (previous {} s)", last.time_s)));
        }
        self.tracks[spatula].push(sample);
        Ok(())
    }

    /// Marks the sample of `spatula` at `time_s` (its last pushed) as a cut.
    pub fn mark_cut(&mut self, spatula: usize, time_s: f64) {
        if self.cuts.len() <= spatula {
            self.cuts.resize_with(spatula + 1, Vec::new);
        }
        if self.cuts[spatula].last().is_none_or(|&t| t < time_s) {
            self.cuts[spatula].push(time_s);
        }
    }

    /// Whether `spatula` cuts at some time in `(after_s, until_s]`.
    pub fn cuts_between(&self, spatula: usize, after_s: f64, until_s: f64) -> bool {
        self.cuts.get(spatula).is_some_and(|c| c.iter().any(|&t| t > after_s && t <= until_s))
    }

    /// Whether any row cuts.
    pub fn has_cuts(&self) -> bool {
        self.cuts.iter().any(|c| !c.is_empty())
    }

    /// Reads a trajectory file (a regular file of at most
    /// [`crate::fsio::Cap::TRAJECTORY`]; anything else is refused unread).
    pub fn load(path: &Path) -> Result<Self, TrajectoryError> {
        let text = crate::fsio::read_regular_text(path, crate::fsio::Cap::TRAJECTORY).map_err(|e| match e {
            crate::fsio::ReadError::Refused { refusal, .. } => TrajectoryError::Refused { path: path.to_path_buf(), refusal },
            crate::fsio::ReadError::Io { source, .. } => TrajectoryError::Io { path: path.to_path_buf(), io: source },
        })?;
        Self::parse(&text, path)
    }

    /// Parses trajectory text; `origin` names the file in errors.
    pub fn parse(text: &str, origin: &Path) -> Result<Self, TrajectoryError> {
        let mut out = Trajectory::new();
        let mut seen_header = false;
        let mut columns = 9;
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let err = |problem: String| TrajectoryError::Line { path: origin.to_path_buf(), line, problem };
            let row = raw.trim();
            if row.is_empty() || row.starts_with('#') {
                continue;
            }
            if !seen_header {
                let cols: Vec<&str> = row.split(',').map(str::trim).collect();
                let joined = cols.join(",");
                if joined == HEADER_WITH_CUT {
                    columns = 10;
                } else if joined != HEADER {
                    return Err(err(format!("expected the header `{HEADER}` (or `{HEADER_WITH_CUT}`), found `{row}`")));
                }
                seen_header = true;
                continue;
            }
            let header = if columns == 10 { HEADER_WITH_CUT } else { HEADER };
            let mut fields = [0.0f64; 9];
            let mut count = 0;
            let mut spatula = 0usize;
            let mut cut = false;
            for (k, cell) in row.split(',').enumerate() {
                if k >= columns {
                    return Err(err(format!("expected {columns} columns ({header}), found more")));
                }
                let cell = cell.trim();
                let name = header.split(',').nth(k).unwrap_or("?");
                if k == 9 {
                    cut = match cell {
                        "0" => false,
                        "1" => true,
                        _ => return Err(err(format!("column cut: `{cell}` must be 0 or 1"))),
                    };
                } else if k == 1 {
                    spatula = cell.parse().map_err(|_| err(format!("column {name}: `{cell}` is not a spatula index")))?;
                    if spatula >= MAX_SPATULAS {
                        return Err(err(format!("column spatula: index {spatula} must be below {MAX_SPATULAS}")));
                    }
                } else {
                    let v: f64 = cell.parse().map_err(|_| err(format!("column {name}: `{cell}` is not a number")))?;
                    if !v.is_finite() {
                        return Err(err(format!("column {name}: must be finite, got {cell}")));
                    }
                    fields[k] = v;
                }
                count += 1;
            }
            if count != columns {
                return Err(err(format!("expected {columns} columns ({header}), found {count}")));
            }
            let sample = Sample {
                time_s: fields[0],
                position_mm: [fields[2], fields[3], fields[4]],
                quaternion: [fields[5], fields[6], fields[7], fields[8]],
            };
            out.push(spatula, sample).map_err(|e| match e {
                TrajectoryError::Sample { problem, .. } => err(problem),
                other => other,
            })?;
            if cut {
                out.mark_cut(spatula, sample.time_s);
            }
        }
        if !seen_header {
            return Err(TrajectoryError::Line {
                path: origin.to_path_buf(),
                line: text.lines().count().max(1),
                problem: format!("no header `{HEADER}` found"),
            });
        }
        Ok(out)
    }

    /// The file text: a comment block, the header, then rows ordered by time
    /// (ties by spatula index), f64 in shortest round-trip form.
    pub fn to_csv(&self) -> String {
        let mut s = String::new();
        s.push_str("# fissure trajectory: time_s in seconds, spatula = index in the scenario's spatulas,\n");
        s.push_str("# x_mm,y_mm,z_mm = spatula-frame origin in millimetres, qw,qx,qy,qz = unit quaternion.\n");
        let with_cut = self.has_cuts();
        if with_cut {
            s.push_str("# cut = 1: microscissors at that blade's tip on that row.\n");
        }
        s.push_str(if with_cut { HEADER_WITH_CUT } else { HEADER });
        s.push('\n');
        let mut cursor = vec![0usize; self.tracks.len()];
        loop {
            let mut next: Option<(usize, f64)> = None;
            for (k, track) in self.tracks.iter().enumerate() {
                if let Some(sample) = track.get(cursor[k])
                    && next.is_none_or(|(_, t)| sample.time_s < t)
                {
                    next = Some((k, sample.time_s));
                }
            }
            let Some((k, _)) = next else { break };
            let sample = &self.tracks[k][cursor[k]];
            write_row(&mut s, k, sample);
            if with_cut {
                s.pop();
                let cut = self.cuts.get(k).is_some_and(|c| c.binary_search_by(|t| t.total_cmp(&sample.time_s)).is_ok());
                let _ = writeln!(s, ",{}", u8::from(cut));
            }
            cursor[k] += 1;
        }
        s
    }

    /// Writes the trajectory to a file (see [`Trajectory::to_csv`]), whole or not at all.
    pub fn save(&self, path: &Path) -> Result<(), TrajectoryError> {
        crate::fsio::write_atomic(path, self.to_csv().as_bytes()).map_err(|e| TrajectoryError::Io { path: path.to_path_buf(), io: e.source })
    }

    /// Number of track slots (highest spatula index with rows + 1).
    pub fn spatula_count(&self) -> usize {
        self.tracks.len()
    }

    /// The samples of one spatula (empty when it has none).
    pub fn samples(&self, spatula: usize) -> &[Sample] {
        self.tracks.get(spatula).map_or(&[], Vec::as_slice)
    }

    /// Time of the latest row of any spatula, s (0 when empty).
    pub fn duration(&self) -> f64 {
        self.tracks.iter().filter_map(|t| t.last()).map(|s| s.time_s).fold(0.0, f64::max)
    }

    /// Time of the earliest row over all tracks, s (0 without rows). A
    /// window recording starts its lead-in (the session before R was pressed)
    /// at a negative time.
    pub fn start_time(&self) -> f64 {
        let earliest = self.tracks.iter().filter_map(|t| t.first()).map(|s| s.time_s).fold(f64::INFINITY, f64::min);
        if earliest.is_finite() { earliest } else { 0.0 }
    }

    /// The pose of `spatula` at `time_s`: linear in position, slerp in rotation,
    /// clamped to the first / last sample outside the recorded range. `None`
    /// when the spatula has no rows or `time_s` is NaN.
    pub fn sample(&self, spatula: usize, time_s: f64) -> Option<Pose> {
        let track = self.tracks.get(spatula)?;
        let first = track.first()?;
        if time_s.is_nan() {
            return None;
        }
        let last = track.last()?;
        if time_s <= first.time_s {
            return Some(to_pose(first));
        }
        if time_s >= last.time_s {
            return Some(to_pose(last));
        }
        // first.time_s < time_s < last.time_s, so 1 <= i < len.
        let i = track.partition_point(|s| s.time_s <= time_s);
        let (a, b) = (&track[i - 1], &track[i]);
        let alpha = (time_s - a.time_s) / (b.time_s - a.time_s);
        let pa = Vec3::from(a.position_mm);
        let pb = Vec3::from(b.position_mm);
        let position = (pa + (pb - pa) * alpha) * 1e-3;
        Some(Pose { position, rotation: slerp(a.quaternion, b.quaternion, alpha) })
    }
}

fn write_row(s: &mut String, spatula: usize, x: &Sample) {
    let _ = writeln!(
        s,
        "{:?},{},{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
        x.time_s,
        spatula,
        x.position_mm[0],
        x.position_mm[1],
        x.position_mm[2],
        x.quaternion[0],
        x.quaternion[1],
        x.quaternion[2],
        x.quaternion[3]
    );
}

fn to_pose(s: &Sample) -> Pose {
    let [w, x, y, z] = s.quaternion;
    Pose { position: Vec3::from(s.position_mm) * 1e-3, rotation: Quat::new_normalize(nalgebra::Quaternion::new(w, x, y, z)) }
}

/// Shortest-arc slerp of two quaternions given as (w, x, y, z) (see [`crate::geometry::slerp`]).
fn slerp(a: [f64; 4], b: [f64; 4], alpha: f64) -> Quat {
    crate::geometry::slerp(&nalgebra::Quaternion::new(a[0], a[1], a[2], a[3]), &nalgebra::Quaternion::new(b[0], b[1], b[2], b[3]), alpha)
}

/// Appends poses to a trajectory file as they happen; every row is written
/// to the file before `record` returns, so a crash loses nothing recorded.
#[derive(Debug)]
pub struct TrajectoryRecorder {
    file: File,
    path: PathBuf,
    row: String,
    last_time: Vec<f64>,
    /// The file has the `cut` column (a scene with tethers: the window's cuts replay).
    with_cut: bool,
}

impl TrajectoryRecorder {
    /// Creates (truncates) the file and writes the comment block and header.
    pub fn create(path: &Path) -> Result<Self, TrajectoryError> {
        Self::create_with_note(path, "")
    }

    /// [`Self::create`] with `note` as a further comment line (none when empty).
    pub fn create_with_note(path: &Path, note: &str) -> Result<Self, TrajectoryError> {
        Self::create_with(path, note, false)
    }

    /// [`Self::create_with_note`], with the `cut` column when `with_cut` (every row then says whether
    /// microscissors cut at that blade's tip in the frame that ends at the row's time; see
    /// [`Self::record_with_cut`]).
    pub fn create_with(path: &Path, note: &str, with_cut: bool) -> Result<Self, TrajectoryError> {
        let io = |io| TrajectoryError::Io { path: path.to_path_buf(), io };
        let mut file = File::create(path).map_err(io)?;
        let mut text = Trajectory::new().to_csv();
        if with_cut {
            text = text.replacen(HEADER, HEADER_WITH_CUT, 1);
            text.insert_str(text.find(HEADER_WITH_CUT).unwrap_or(0), "# cut = 1: microscissors at that blade's tip on that row.\n");
        }
        if !note.is_empty() {
            text.insert_str(0, &format!("# {}\n", note.replace('\n', " ")));
        }
        file.write_all(text.as_bytes()).map_err(io)?;
        file.flush().map_err(io)?;
        Ok(Self { file, path: path.to_path_buf(), row: String::with_capacity(192), last_time: Vec::new(), with_cut })
    }

    /// Appends one pose (metres) for `spatula` at `time_s`; checks it like
    /// [`Trajectory::push`] and writes it through to the file.
    pub fn record(&mut self, time_s: f64, spatula: usize, pose: &Pose) -> Result<(), TrajectoryError> {
        self.record_with_cut(time_s, spatula, pose, false)
    }

    /// [`Self::record`], marking the row as a cut at the blade's tip when `cut` (a replay cuts in the frame whose
    /// end time is the row's, as the window did). A cut in a file without the `cut` column is refused.
    pub fn record_with_cut(&mut self, time_s: f64, spatula: usize, pose: &Pose, cut: bool) -> Result<(), TrajectoryError> {
        let sample = Sample::from_pose(time_s, pose);
        let bad = |problem: String| TrajectoryError::Sample { spatula, time_s, problem };
        if spatula >= MAX_SPATULAS {
            return Err(bad(format!("spatula index must be below {MAX_SPATULAS}")));
        }
        sample.check().map_err(bad)?;
        if self.last_time.len() <= spatula {
            self.last_time.resize(spatula + 1, f64::NEG_INFINITY);
        }
        if time_s <= self.last_time[spatula] {
            return Err(bad(format!("times must strictly increase per spatula (previous {} s)", self.last_time[spatula])));
        }
        if cut && !self.with_cut {
            return Err(bad("a cut in a recording made without the `cut` column".into()));
        }
        self.row.clear();
        write_row(&mut self.row, spatula, &sample);
        if self.with_cut {
            self.row.pop();
            let _ = writeln!(self.row, ",{}", u8::from(cut));
        }
        let io = |io| TrajectoryError::Io { path: self.path.clone(), io };
        self.file.write_all(self.row.as_bytes()).map_err(io)?;
        self.file.flush().map_err(io)?;
        self.last_time[spatula] = time_s;
        Ok(())
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q_axis_angle(axis: [f64; 3], deg: f64) -> [f64; 4] {
        let q = Quat::from_axis_angle(&nalgebra::Unit::new_normalize(Vec3::from(axis)), deg.to_radians());
        [q.w, q.i, q.j, q.k]
    }

    fn example() -> Trajectory {
        let mut t = Trajectory::new();
        t.push(0, Sample { time_s: 0.0, position_mm: [0.0, 0.0, 0.0], quaternion: [1.0, 0.0, 0.0, 0.0] }).expect("valid");
        t.push(0, Sample { time_s: 2.0, position_mm: [10.0, -4.0, 0.1], quaternion: q_axis_angle([0.0, 0.0, 1.0], 90.0) })
            .expect("valid");
        t.push(1, Sample { time_s: 0.5, position_mm: [1.0 / 3.0, 1e-300, -7.25], quaternion: q_axis_angle([1.0, 2.0, 3.0], 37.0) })
            .expect("valid");
        t
    }

    #[test]
    fn save_then_load_is_exact() {
        let t = example();
        let text = t.to_csv();
        let back = Trajectory::parse(&text, Path::new("t.csv")).expect("own output must parse");
        assert_eq!(back, t, "round trip must keep every f64 bit for bit:\n{text}");
        assert_eq!(back.to_csv(), text, "and print identically");
    }

    #[test]
    fn sample_interpolates_and_clamps() {
        let t = example();
        let mid = t.sample(0, 1.0).expect("track 0 exists");
        assert!((mid.position - Vec3::new(5.0e-3, -2.0e-3, 0.05e-3)).norm() < 1e-15, "linear position in metres: {:?}", mid.position);
        let expected = Quat::from_axis_angle(&Vec3::z_axis(), 45f64.to_radians());
        assert!(mid.rotation.angle_to(&expected) < 1e-12, "slerp half way is 45 degrees about z");
        let before = t.sample(0, -3.0).expect("clamped");
        assert_eq!(before.position, Vec3::zeros(), "before the first sample: the first pose");
        let after = t.sample(0, 99.0).expect("clamped");
        assert!((after.position - Vec3::new(0.010, -0.004, 0.0001)).norm() < 1e-15, "after the last: the last pose");
        assert!(t.sample(2, 0.0).is_none(), "no track 2");
        assert!(t.sample(0, f64::NAN).is_none(), "NaN time");
        assert_eq!(t.duration(), 2.0);
    }

    #[test]
    fn slerp_takes_the_short_way_for_sign_flipped_quaternions() {
        let a = q_axis_angle([0.0, 1.0, 0.0], 10.0);
        let b = q_axis_angle([0.0, 1.0, 0.0], 30.0).map(|c| -c);
        let q = slerp(a, b, 0.5);
        let want = Quat::from_axis_angle(&Vec3::y_axis(), 20f64.to_radians());
        assert!(q.angle_to(&want) < 1e-12, "slerp of q and -q' must equal slerp of q and q'");
        let same = slerp(a, a, 0.3);
        assert!(same.coords.iter().all(|c| c.is_finite()), "identical inputs must not give NaN");
    }

    #[test]
    fn bad_rows_name_the_line() {
        let head = format!("# c\n{HEADER}\n");
        let cases = [
            ("0,0,0,0,0,1,0,0,0\n0,0,0,0,0,1,0,0,0\n", 4, "strictly increase"),
            ("0,0,0,0,0,NaN,0,0,0\n", 3, "finite"),
            ("0,0,0,0,0,2,0,0,0\n", 3, "unit"),
            ("0,0,0,0,0,1,0,0\n", 3, "9 columns"),
            ("0,0,0,0,0,1,0,0,0,0\n", 3, "9 columns"),
            ("0,x,0,0,0,1,0,0,0\n", 3, "spatula index"),
            ("0,999,0,0,0,1,0,0,0\n", 3, "below 256"),
            ("0,0,abc,0,0,1,0,0,0\n", 3, "x_mm"),
        ];
        for (rows, line, want) in cases {
            let text = format!("{head}{rows}");
            match Trajectory::parse(&text, Path::new("bad.csv")) {
                Err(TrajectoryError::Line { line: l, problem, path }) => {
                    assert_eq!(l, line, "line of the error in {rows:?}: {problem}");
                    assert!(problem.contains(want), "{rows:?}: `{problem}` should mention `{want}`");
                    assert_eq!(path, Path::new("bad.csv"));
                }
                other => panic!("{rows:?} must fail with a line error, got {other:?}"),
            }
        }
        let no_header = Trajectory::parse("0,0,0,0,0,1,0,0,0\n", Path::new("x.csv")).expect_err("no header");
        assert!(no_header.to_string().contains("x.csv:1"), "{no_header}");
    }

    #[test]
    fn recorder_writes_through_and_reads_back() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("rec.csv");
        let mut rec = TrajectoryRecorder::create(&path).expect("create");
        let pose = |x: f64| Pose { position: Vec3::new(x, 0.02, -0.001), rotation: Quat::from_axis_angle(&Vec3::x_axis(), x) };
        for k in 0..5 {
            let t = k as f64 * 0.01;
            rec.record(t, 0, &pose(t)).expect("record 0");
            rec.record(t, 1, &pose(-t)).expect("record 1");
            // Read while the recorder is still open: every row is already in the file.
            let now = Trajectory::load(&path).expect("partial file parses");
            assert_eq!(now.samples(1).len(), k + 1, "rows written through after record {k}");
        }
        assert!(rec.record(0.0, 0, &pose(0.0)).is_err(), "time going back must be refused");
        let back = Trajectory::load(&path).expect("load");
        let p = back.sample(0, 0.03).expect("track 0");
        assert!((p.position - pose(0.03).position).norm() < 1e-15, "recorded position comes back in metres");
        assert!(p.rotation.angle_to(&pose(0.03).rotation) < 1e-12);
    }

    #[test]
    fn a_recording_with_the_cut_column_reads_back_its_cuts_in_the_frame_that_ends_at_the_row() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("rec.csv");
        let mut rec = TrajectoryRecorder::create_with(&path, "a window session", true).expect("create");
        let pose = |x: f64| Pose { position: Vec3::new(x, 0.0, 0.0), rotation: Quat::identity() };
        for k in 0..4 {
            let t = k as f64 * 0.01;
            rec.record_with_cut(t, 0, &pose(t), k == 2).expect("record 0");
            rec.record(t, 1, &pose(-t)).expect("record 1");
        }
        let back = Trajectory::load(&path).expect("load");
        assert!(back.has_cuts());
        assert!(back.cuts_between(0, 0.01, 0.02), "the cut on the row at 0.02 s belongs to the frame ending then");
        assert!(!back.cuts_between(0, 0.02, 0.03) && !back.cuts_between(1, f64::NEG_INFINITY, 1.0));
        let mut plain = TrajectoryRecorder::create(&dir.path().join("plain.csv")).expect("create");
        let e = plain.record_with_cut(0.0, 0, &pose(0.0), true).expect_err("no cut column");
        assert!(e.to_string().contains("cut"), "{e}");
    }
}
