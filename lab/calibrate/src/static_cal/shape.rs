//! A branch tie's design on curves of a shape: the cycling fit's bias curves as free nodes or
//! as nodes on a cubic (the static fit builds its designs itself, through the same node
//! basis).

use super::fit::{node_basis, push_branch_ties, BranchMode, CurveShape};

impl BranchMode {
    /// Unknowns of this tie on curves of `shape` over `g` nodes.
    #[must_use]
    pub(crate) fn shaped_unknowns(self, shape: CurveShape, g: usize) -> usize {
        let c = shape.unknowns(g);
        match self {
            Self::Single => c,
            Self::Offset => c + 1,
            Self::Free => 2 * c,
        }
    }

    /// A design row in node space (this tie's [`Self::unknowns`] columns) on curves of
    /// `shape`: each curve's `g` node columns through the shape's node basis, the step column
    /// kept.
    #[must_use]
    pub(crate) fn shaped_row(self, shape: CurveShape, row: &[f64], g: usize) -> Vec<f64> {
        if shape == CurveShape::Nodes {
            return row.to_vec();
        }
        let c = shape.unknowns(g);
        let basis = node_basis(shape, g, c);
        let curves = if self == Self::Free { 2 } else { 1 };
        let mut out = vec![0.0; self.shaped_unknowns(shape, g)];
        for b in 0..curves {
            for (j, bj) in basis.iter().enumerate() {
                for (k, v) in bj.iter().enumerate() {
                    out[b * c + k] += row[b * g + j] * v;
                }
            }
        }
        if self == Self::Offset {
            out[c] = row[g];
        }
        out
    }

    /// Heating and cooling nodes from coefficients on curves of `shape` ([`Self::expand`]
    /// for free nodes).
    #[must_use]
    pub(crate) fn expand_shaped(self, shape: CurveShape, coef: &[f64], g: usize) -> (Vec<f64>, Vec<f64>) {
        if shape == CurveShape::Nodes {
            return self.expand(coef, g);
        }
        let c = shape.unknowns(g);
        let basis = node_basis(shape, g, c);
        let curves = if self == Self::Free { 2 } else { 1 };
        let mut nodes = vec![0.0; self.unknowns(g)];
        for b in 0..curves {
            for (j, bj) in basis.iter().enumerate() {
                nodes[b * g + j] = bj.iter().zip(&coef[b * c..(b + 1) * c]).map(|(v, k)| v * k).sum();
            }
        }
        if self == Self::Offset {
            nodes[g] = coef[c];
        }
        self.expand(&nodes, g)
    }

    /// [`Self::push_regularisers`] on curves of `shape`: a cubic needs none, but for Free
    /// its two curves are tied weakly, as free nodes are.
    pub(crate) fn push_shaped_regularisers(
        self,
        shape: CurveShape,
        xb: &mut Vec<f64>,
        yb: &mut Vec<f64>,
        p: usize,
        g: usize,
    ) {
        match shape {
            CurveShape::Nodes => self.push_regularisers(xb, yb, p, g),
            CurveShape::Cubic if self == Self::Free => push_branch_ties(xb, yb, p, shape.unknowns(g)),
            CurveShape::Cubic => {}
        }
    }
}
