//! One-dimensional piecewise-linear distributions: a density given at nodes `x₀ < x₁ < … < x_n`,
//! linear in between, sampled exactly in O(1).
//!
//! Sampling picks a cell with Walker's alias method (Vose 1991's construction: one table lookup and
//! one comparison, whatever the number of cells) and then inverts the cell's linear density in closed
//! form. With end values `a`, `b` and a uniform `v`, the fraction `t` of the cell solves
//! `a t + (b − a) t²/2 = v (a + b)/2`, whose root written as
//!
//! ```text
//! t = v (a + b) / (a + √((1 − v) a² + v b²))
//! ```
//!
//! has no cancellation for `a ≈ b` (it reduces to `t = v`) nor for `a = 0` (`t = √v`), and no
//! division by `b − a`. So [`PiecewiseLinear::pdf`] is the exact density of what
//! [`PiecewiseLinear::sample`] draws, up to rounding.

use std::fmt;

/// Why a table cannot define a distribution.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TableError {
    /// Fewer than two nodes, columns of different lengths, or a grid not spanning its domain.
    Invalid(String),
    /// A node or value is NaN or infinite (index of the first one).
    NotFinite(usize),
    /// A value is negative (index of the first one).
    Negative(usize),
    /// The nodes do not strictly increase (index of the first node not above its predecessor).
    NotIncreasing(usize),
    /// All values are zero: nothing to sample.
    Empty,
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableError::Invalid(s) => write!(f, "{s}"),
            TableError::NotFinite(i) => write!(f, "entry {i} is not a finite number"),
            TableError::Negative(i) => write!(f, "value {i} is negative; a density must be ≥ 0"),
            TableError::NotIncreasing(i) => write!(f, "the grid is not strictly monotone at entry {i}"),
            TableError::Empty => write!(f, "all values are zero; the table has no probability to sample"),
        }
    }
}

/// A cell's geometry: `[lo, lo + width]` with normalised end densities `a`, `b`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    lo: f64,
    width: f64,
    a: f64,
    b: f64,
}

/// One alias-table entry: a cell with the geometry of both outcomes stored inline, so that a draw
/// touches one entry (one random memory access: sampling went from 2.0× to 1.5× the cost of HG, `phase/` benches).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Cell {
    /// Keep this cell when the fractional part of `u·n` is below `threshold` …
    threshold: f64,
    /// … and then rescale that fraction by `1/threshold` …
    inv_threshold: f64,
    /// … otherwise take the alias, rescaling by `1/(1 − threshold)`.
    inv_rest: f64,
    own: Piece,
    alias: Piece,
}

/// A normalised piecewise-linear density on `[x₀, x_n]`.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseLinear {
    nodes: Vec<f64>,
    /// Normalised density at each node.
    density: Vec<f64>,
    /// Cumulative probability at each node (`cdf[0] = 0`, `cdf[n] = 1`).
    cdf: Vec<f64>,
    cells: Vec<Cell>,
    /// The integral of the values as given, before normalisation.
    raw_integral: f64,
}

const ONE_BELOW: f64 = 1.0 - f64::EPSILON / 2.0;

impl PiecewiseLinear {
    /// The distribution with density proportional to the linear interpolation of `values` at
    /// `nodes`. Nodes must strictly increase; values must be finite, ≥ 0 and not all zero.
    pub fn new(nodes: &[f64], values: &[f64]) -> Result<Self, TableError> {
        if nodes.len() != values.len() {
            return Err(TableError::Invalid(format!(
                "{} grid points but {} values; the two columns must have the same length",
                nodes.len(),
                values.len()
            )));
        }
        if nodes.len() < 2 {
            return Err(TableError::Invalid(format!("{} grid point(s); at least 2 are needed", nodes.len())));
        }
        if let Some(i) = nodes.iter().zip(values).position(|(x, v)| !x.is_finite() || !v.is_finite()) {
            return Err(TableError::NotFinite(i));
        }
        if let Some(i) = values.iter().position(|&v| v < 0.0) {
            return Err(TableError::Negative(i));
        }
        if let Some(i) = nodes.windows(2).position(|w| w[1] <= w[0]) {
            return Err(TableError::NotIncreasing(i + 1));
        }
        let cells = nodes.len() - 1;
        let mass: Vec<f64> =
            (0..cells).map(|i| 0.5 * (values[i] + values[i + 1]) * (nodes[i + 1] - nodes[i])).collect();
        let total: f64 = mass.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return Err(TableError::Empty);
        }
        let density: Vec<f64> = values.iter().map(|v| v / total).collect();
        let mut cdf = Vec::with_capacity(nodes.len());
        cdf.push(0.0);
        let mut acc = 0.0;
        for m in &mass {
            acc += m / total;
            cdf.push(acc);
        }
        // Absorb the rounding of the running sum so that the last node is exactly 1.
        let last = acc;
        for c in &mut cdf {
            *c /= last;
        }
        let (threshold, alias) = alias_table(&mass, total);
        let piece = |i: usize| Piece { lo: nodes[i], width: nodes[i + 1] - nodes[i], a: density[i], b: density[i + 1] };
        let cells = (0..cells)
            .map(|i| Cell {
                threshold: threshold[i],
                inv_threshold: if threshold[i] > 0.0 { 1.0 / threshold[i] } else { 0.0 },
                inv_rest: if threshold[i] < 1.0 { 1.0 / (1.0 - threshold[i]) } else { 0.0 },
                own: piece(i),
                alias: piece(alias[i] as usize),
            })
            .collect();
        Ok(PiecewiseLinear { nodes: nodes.to_vec(), density, cdf, cells, raw_integral: total })
    }

    /// Draw from the distribution with one uniform `u ∈ [0, 1)`.
    #[inline(always)]
    pub fn sample(&self, u: f64) -> f64 {
        let n = self.cells.len();
        let scaled = u * n as f64;
        let i = (scaled as usize).min(n - 1);
        let frac = scaled - i as f64;
        let frac = if frac < ONE_BELOW { frac } else { ONE_BELOW };
        let here = &self.cells[i];
        let (cell, v) = if frac < here.threshold {
            (&here.own, frac * here.inv_threshold)
        } else {
            (&here.alias, (frac - here.threshold) * here.inv_rest)
        };
        let (a, b) = (cell.a, cell.b);
        // The denominator is 0 only for a = 0 at v = 0, where t = 0.
        let den = a + ((1.0 - v) * a * a + v * b * b).sqrt();
        let t = v * (a + b) / den.max(f64::MIN_POSITIVE);
        let t = if t < 1.0 { t } else { 1.0 };
        cell.lo + t * cell.width
    }

    /// The normalised density at `x` (0 outside the nodes).
    pub fn pdf(&self, x: f64) -> f64 {
        match self.cell_of(x) {
            Some(i) => {
                let c = &self.cells[i].own;
                let t = (x - c.lo) / c.width;
                c.a + (c.b - c.a) * t
            }
            None => 0.0,
        }
    }

    /// The cumulative probability `P(X ≤ x)` of the distribution, exactly (for tests and binning).
    pub fn cdf(&self, x: f64) -> f64 {
        if x <= self.nodes[0] {
            return 0.0;
        }
        match self.cell_of(x) {
            Some(i) => {
                let c = &self.cells[i].own;
                let t = (x - c.lo) / c.width;
                (self.cdf[i] + c.width * t * (c.a + 0.5 * (c.b - c.a) * t)).min(1.0)
            }
            None => 1.0,
        }
    }

    /// `E[X]`, exactly for the piecewise-linear density.
    pub fn mean(&self) -> f64 {
        // ∫ x (a + (b − a)(x − lo)/w) dx over a cell = w (lo (a + b)/2 + w (a + 2b)/6).
        self.cells
            .iter()
            .map(|c| &c.own)
            .map(|c| c.width * (c.lo * 0.5 * (c.a + c.b) + c.width * (c.a + 2.0 * c.b) / 6.0))
            .sum()
    }

    /// The cell holding `x`, if `x` lies within the nodes.
    fn cell_of(&self, x: f64) -> Option<usize> {
        let (first, last) = (self.nodes[0], self.nodes[self.nodes.len() - 1]);
        if !(first..=last).contains(&x) {
            return None;
        }
        Some(self.nodes.partition_point(|&n| n <= x).saturating_sub(1).min(self.cells.len() - 1))
    }

    /// The nodes.
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// The normalised density at each node.
    pub fn densities(&self) -> &[f64] {
        &self.density
    }

    /// The integral of the values as given (the normalisation that was divided out).
    pub fn raw_integral(&self) -> f64 {
        self.raw_integral
    }
}

/// Walker alias table (Vose's construction) for probabilities `mass/total`: per cell, the
/// probability of keeping it and the cell that receives the rest.
fn alias_table(mass: &[f64], total: f64) -> (Vec<f64>, Vec<u32>) {
    let n = mass.len();
    let mut scaled: Vec<f64> = mass.iter().map(|m| m / total * n as f64).collect();
    let mut threshold = vec![1.0; n];
    let mut alias: Vec<u32> = (0..n as u32).collect();
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
        small.pop();
        threshold[s] = scaled[s];
        alias[s] = l as u32;
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // What is left is 1 up to rounding: keep those cells whole.
    for i in small.into_iter().chain(large) {
        threshold[i] = 1.0;
        alias[i] = i as u32;
    }
    // A cell with zero mass must never be kept (its rescaled fraction would be undefined) and must
    // hand its share to a cell that has mass.
    let heaviest = (0..n).fold(0, |best, i| if mass[i] > mass[best] { i } else { best });
    for i in 0..n {
        if mass[i] == 0.0 {
            threshold[i] = 0.0;
            if alias[i] as usize == i {
                alias[i] = heaviest as u32;
            }
        }
    }
    (threshold, alias)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_tables() {
        assert!(matches!(PiecewiseLinear::new(&[0.0], &[1.0]), Err(TableError::Invalid(_))));
        assert!(matches!(PiecewiseLinear::new(&[0.0, 1.0], &[1.0]), Err(TableError::Invalid(_))));
        assert_eq!(PiecewiseLinear::new(&[0.0, 1.0], &[1.0, f64::NAN]), Err(TableError::NotFinite(1)));
        assert_eq!(PiecewiseLinear::new(&[0.0, 1.0, 2.0], &[1.0, -1e-9, 1.0]), Err(TableError::Negative(1)));
        assert_eq!(PiecewiseLinear::new(&[0.0, 1.0, 1.0], &[1.0, 1.0, 1.0]), Err(TableError::NotIncreasing(2)));
        assert_eq!(PiecewiseLinear::new(&[0.0, 1.0], &[0.0, 0.0]), Err(TableError::Empty));
    }

    #[test]
    fn normalised_and_exact_moments() {
        // Density ∝ x on [0, 2]: pdf x/2, mean 4/3.
        let d = PiecewiseLinear::new(&[0.0, 1.0, 2.0], &[0.0, 3.0, 6.0]).unwrap();
        assert!((d.pdf(1.5) - 0.75).abs() < 1e-15);
        assert!((d.cdf(1.0) - 0.25).abs() < 1e-15);
        assert!((d.mean() - 4.0 / 3.0).abs() < 1e-15);
        assert_eq!(d.raw_integral(), 6.0);
        assert_eq!(d.pdf(2.5), 0.0);
    }

    #[test]
    fn inverse_is_exact_on_a_single_cell() {
        // One cell: the alias step is the identity, so sample(u) must invert the CDF exactly.
        for (a, b) in [(1.0, 1.0), (0.0, 1.0), (1.0, 0.0), (3.0, 1e-12), (1e-12, 5.0)] {
            let d = PiecewiseLinear::new(&[2.0, 5.0], &[a, b]).unwrap();
            for k in 0..=100 {
                let u = (k as f64 / 100.0).min(ONE_BELOW);
                let x = d.sample(u);
                assert!((2.0..=5.0).contains(&x));
                assert!((d.cdf(x) - u).abs() < 1e-12, "a={a} b={b} u={u}: cdf(sample) = {}", d.cdf(x));
            }
        }
    }

    #[test]
    fn zero_mass_cells_are_never_drawn() {
        let d = PiecewiseLinear::new(&[0.0, 1.0, 2.0, 3.0, 4.0], &[0.0, 0.0, 1.0, 0.0, 0.0]).unwrap();
        for k in 0..100_000 {
            let x = d.sample(k as f64 / 100_000.0);
            assert!((1.0..=3.0).contains(&x), "drew {x} from a zero-density cell");
        }
        assert!((1.0..=3.0).contains(&d.sample(ONE_BELOW)));
    }

    #[test]
    fn alias_keeps_cell_probabilities() {
        // Walk u over a fine uniform grid: the fraction landing in each cell equals its mass
        // up to the grid resolution (the alias map is measure-preserving).
        let nodes = [0.0, 0.1, 0.5, 0.6, 2.0, 3.0];
        let values = [5.0, 1.0, 0.0, 7.0, 0.5, 2.0];
        let d = PiecewiseLinear::new(&nodes, &values).unwrap();
        let k = 1_000_000;
        let mut counts = [0usize; 5];
        for j in 0..k {
            let x = d.sample((j as f64 + 0.5) / k as f64);
            counts[nodes.partition_point(|&n| n <= x).saturating_sub(1).min(4)] += 1;
        }
        for i in 0..5 {
            let p = d.cdf(nodes[i + 1]) - d.cdf(nodes[i]);
            assert!((counts[i] as f64 / k as f64 - p).abs() < 1e-5, "cell {i}: {} vs {p}", counts[i]);
        }
    }
}
