//! `scripts/cholmod_compare.sh`'s output read back: each round prints, for a mesh (`== NAME`), a line from our
//! factor (`examples/factor_compare.rs`) and one from CHOLMOD (`scripts/cholmod_compare.c`) per ordering, both
//! in the same words (`fissure metis: n N, nnz(L) exact X M, ..., numeric T s, 96-column solve S ms`).
//! The C side writes text, so this is the one figure of the page read from printed lines; the words are the
//! two programs' own, and a unit test holds them.

/// Which figure of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// Entries of L, counted exactly.
    Exact,
    /// Numeric factorization time.
    Numeric,
    /// The 96-column solve's time.
    Solve,
}

impl Field {
    fn key(self) -> &'static str {
        match self {
            Field::Exact => "nnz(L) exact ",
            Field::Numeric => "numeric ",
            Field::Solve => "solve ",
        }
    }
}

/// The number after `key` in `line`.
fn number_after(line: &str, key: &str) -> Option<f64> {
    let rest = &line[line.find(key)? + key.len()..];
    let end = rest.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// The median over rounds of ours / CHOLMOD's for one mesh, ordering and figure (NaN when the log has none).
pub fn ratio(log: &str, mesh: &str, ordering: &str, field: Field) -> f64 {
    let mut on = false;
    let mut ours: Option<f64> = None;
    let mut ratios = Vec::new();
    let tag = format!("{ordering}:");
    for line in log.lines() {
        let mut words = line.split_whitespace();
        let (first, second) = (words.next().unwrap_or_default(), words.next().unwrap_or_default());
        if first == "==" {
            on = second == mesh;
            continue;
        }
        if !on || second != tag {
            continue;
        }
        let v = number_after(line, field.key());
        match (first, v, ours) {
            ("fissure", Some(v), _) => ours = Some(v),
            ("cholmod", Some(theirs), Some(o)) if theirs > 0.0 => {
                ratios.push(o / theirs);
                ours = None;
            }
            _ => {}
        }
    }
    super::summary::median(ratios)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOG: &str = "\
BLAS: /usr/lib/x86_64-linux-gnu/libblas.so.3; CPU: AMD EPYC
== brain_pial_coarse
-- round 1
fissure metis: n 77271, nnz(L) exact 16.960 M, stored 21.920 M, analysis 0.410 s, numeric 1.200 s, 96-column solve 40.0 ms
fissure amd: n 77271, nnz(L) exact 23.040 M, stored 32.710 M, analysis 0.300 s, numeric 2.000 s, 96-column solve 50.0 ms
cholmod metis: n 77271, nnz(L) exact 16.000 M, stored 16.000 M, analysis 0.500 s, numeric 1.500 s, 96-column solve 50.0 ms
cholmod amd: n 77271, nnz(L) exact 23.040 M, stored 23.040 M, analysis 0.200 s, numeric 2.500 s, 96-column solve 40.0 ms
-- round 2
fissure metis: n 77271, nnz(L) exact 16.960 M, stored 21.920 M, analysis 0.410 s, numeric 1.000 s, 96-column solve 40.0 ms
cholmod metis: n 77271, nnz(L) exact 16.000 M, stored 16.000 M, analysis 0.500 s, numeric 2.000 s, 96-column solve 50.0 ms
== brain_pial_q15
-- round 1
fissure metis: n 188124, nnz(L) exact 60.000 M, stored 70.000 M, analysis 1.0 s, numeric 6.000 s, 96-column solve 150.0 ms
cholmod metis: n 188124, nnz(L) exact 50.000 M, stored 50.000 M, analysis 1.0 s, numeric 4.000 s, 96-column solve 100.0 ms
";

    #[test]
    fn pairs_ours_with_cholmods_line_by_mesh_and_ordering_and_takes_the_median_of_rounds() {
        assert!((ratio(LOG, "brain_pial_coarse", "metis", Field::Exact) - 1.06).abs() < 1e-12);
        // Rounds 1.2 / 1.5 = 0.8 and 1.0 / 2.0 = 0.5: the median of two is their mean.
        assert!((ratio(LOG, "brain_pial_coarse", "metis", Field::Numeric) - 0.65).abs() < 1e-12);
        assert!((ratio(LOG, "brain_pial_coarse", "amd", Field::Solve) - 1.25).abs() < 1e-12);
        assert!((ratio(LOG, "brain_pial_q15", "metis", Field::Numeric) - 1.5).abs() < 1e-12);
        assert!(ratio(LOG, "brain_pial_q15", "amd", Field::Numeric).is_nan(), "no AMD line for q15");
        assert!(ratio(LOG, "elsewhere", "metis", Field::Exact).is_nan());
    }
}
