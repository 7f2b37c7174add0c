//! A discrete distribution over `0..n` given by weights, drawn by inverting its cumulative shares
//! (a binary search: the lists here are short — a medium's populations, a size class's drops).

/// Cumulative shares of `n` weights; the last is exactly 1, so every `u ∈ [0, 1)` finds an index.
#[derive(Debug, Clone, PartialEq)]
pub struct Discrete {
    cumulative: Box<[f64]>,
}

impl Discrete {
    /// Bytes of the cumulative table on the heap.
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.cumulative)
    }

    /// From weights that are finite and ≥ 0 with a positive sum; `None` otherwise.
    pub fn new(weights: impl IntoIterator<Item = f64>) -> Option<Self> {
        let weights: Vec<f64> = weights.into_iter().collect();
        let total: f64 = weights.iter().sum();
        if !(total > 0.0 && total.is_finite()) || weights.iter().any(|w| w.is_nan() || *w < 0.0) {
            return None;
        }
        let mut acc = 0.0;
        let mut cumulative: Vec<f64> = weights
            .iter()
            .map(|w| {
                acc += w;
                acc / total
            })
            .collect();
        *cumulative.last_mut()? = 1.0;
        Some(Discrete { cumulative: cumulative.into() })
    }

    /// The index of the uniform number `u ∈ [0, 1)`: the first whose cumulative share exceeds it.
    #[inline]
    pub fn index(&self, u: f64) -> usize {
        self.cumulative.partition_point(|&c| c <= u).min(self.cumulative.len() - 1)
    }

    /// The share of every index (summing to 1).
    pub fn shares(&self) -> impl Iterator<Item = f64> + '_ {
        let mut prev = 0.0;
        self.cumulative.iter().map(move |&c| {
            let w = c - prev;
            prev = c;
            w
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_follow_the_weights() {
        let d = Discrete::new([1.0, 0.0, 3.0]).unwrap();
        assert_eq!((d.index(0.0), d.index(0.2499), d.index(0.25), d.index(0.999_999)), (0, 0, 2, 2));
        assert_eq!(d.shares().collect::<Vec<_>>(), vec![0.25, 0.0, 0.75]);
        assert!(Discrete::new([]).is_none() && Discrete::new([0.0]).is_none());
        assert!(Discrete::new([1.0, -1.0]).is_none() && Discrete::new([f64::NAN]).is_none());
    }
}
