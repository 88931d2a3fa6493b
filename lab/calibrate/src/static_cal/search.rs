//! Static calibration's model search ([`crate::static_cal`], *Model choice*): every
//! candidate's cross-validation on each row set, the lowest chosen, and the path of one part
//! at a time that leads to it.

use crate::fit::{fit_static_traced, StaticSeries, StaticStructure, StaticTraces};
use crate::static_cal::choice::{self, cv_rms_axes, SearchStep};
use crate::static_cal::{FigureFault, Run, StaticCalError};

/// What the model search found for one axis, on every row (the table's rows).
pub(crate) struct AxisChoice {
    /// The search's path: its start and every step it took, the last the choice.
    pub(crate) path: Vec<SearchStep>,
    /// The table's refusals: every candidate (its name) the search tried that could not be
    /// fitted on every row, and why.
    pub(crate) refused: Vec<(String, crate::fit::FitError)>,
}

impl AxisChoice {
    /// The choice (CV RMS, structure): the search's last step; an error, with the first
    /// refusal, when no candidate could be fitted.
    pub(crate) fn chosen(&self, axis: &str) -> Result<(f64, StaticStructure), StaticCalError> {
        self.path.last().map(|st| (st.cv_rms_g, st.structure)).ok_or_else(|| {
            StaticCalError::Figure(FigureFault::NoCandidate {
                axis: axis.to_string(),
                first_refusal: self.refused.first().map(|r| Box::new(r.clone())),
            })
        })
    }
}

/// Every axis's cross-validation RMS of the structures tried on one row set, each computed
/// once (the axes share each fold's design).
struct Tried {
    structures: Vec<StaticStructure>,
    cv: Vec<Vec<Result<f64, crate::fit::FitError>>>,
}

/// The model search ([`crate::static_cal`], *Model choice*) on every row, for every axis:
/// every candidate's blocked cross-validation RMS, the lowest chosen, and the path from the
/// simplest candidate to it ([`path_to`]). A log with one branch gets
/// [`super::ONE_BRANCH`] alone. Figures are computed once per structure, for every axis at
/// once (the traces depend on the temperatures only). The table and every held-out figure
/// of ours hold this one choice, so no fold searches on its own.
pub(crate) fn choose_structures(run: &Run<'_>, progress: bool) -> Vec<AxisChoice> {
    let opts = run.opts;
    let na = run.log.axes.len();
    let set = &run.sets[0];
    let candidates = run.candidates(0);
    let pb =
        if progress { indicatif::ProgressBar::new(candidates.len() as u64) } else { indicatif::ProgressBar::hidden() };
    let mut choices: Vec<AxisChoice> = (0..na).map(|_| AxisChoice { path: Vec::new(), refused: Vec::new() }).collect();
    let axes: Vec<StaticSeries<'_>> = (0..na).map(|a| run.series(a)).collect();
    let mut tried = Tried { structures: Vec::new(), cv: Vec::new() };
    for st in &candidates {
        let traces = StaticTraces::new(&axes[0], st, opts.deadband_c_per_min);
        let cv = cv_rms_axes(&axes, &traces, &set.rows, run.k_sel, opts);
        for (choice, r) in choices.iter_mut().zip(&cv) {
            if let Err(e) = r {
                choice.refused.push((st.name(), e.clone()));
            }
        }
        tried.structures.push(*st);
        tried.cv.push(cv);
        pb.inc(1);
    }
    pb.finish_and_clear();
    // A choice is a table the rows give: a structure whose table is refused (its terms past
    // the root crate's bounds on that grid, where the cross-validation's folds passed) is
    // refused and the search takes the next. Traces built once per structure.
    let mut checked: Vec<(StaticStructure, StaticTraces)> = Vec::new();
    for (a, ch) in choices.iter_mut().enumerate() {
        while let Some(end) = path_to_end(&mut ch.path, &tried, a, opts.grid_points) {
            let k = checked.iter().position(|c| c.0 == end).unwrap_or_else(|| {
                checked.push((end, StaticTraces::new(&axes[0], &end, opts.deadband_c_per_min)));
                checked.len() - 1
            });
            let fit = fit_static_traced(&axes[a], &checked[k].1, &set.mask, opts.grid_points, opts.block);
            let Err(e) = fit else { break };
            tried.cv.iter_mut().zip(&tried.structures).filter(|c| *c.1 == end).for_each(|c| c.0[a] = Err(e.clone()));
            ch.refused.push((end.name(), e));
        }
    }
    choices
}

/// Set `path` to axis `a`'s [`path_to`] on `t`; its end, the choice.
fn path_to_end(path: &mut Vec<SearchStep>, t: &Tried, a: usize, g: usize) -> Option<StaticStructure> {
    *path = path_to(t, a, g);
    path.last().map(|x| x.structure)
}

/// Axis `a`'s path on one set: the simplest structure tried that could be fitted, then one
/// step at a time ([`choice::is_step`]) towards the structure with the lowest CV RMS (the
/// choice, the path's end), each step the one of the choice's remaining parts whose
/// structure has the lowest CV RMS. Every structure on the path is a candidate (the lattice
/// holds every combination of its parts), so each has its own figure; a step may raise the
/// figure (a part that pays only with a later one), and the path says so. Empty when no
/// structure could be fitted.
fn path_to(t: &Tried, a: usize, g: usize) -> Vec<SearchStep> {
    let fitted: Vec<SearchStep> = t
        .structures
        .iter()
        .zip(&t.cv)
        .filter_map(|(st, cv)| cv[a].as_ref().ok().map(|&r| SearchStep { structure: *st, cv_rms_g: r }))
        .collect();
    // The lowest figure; among equals, the first tried (the lattice's order).
    let Some(best) =
        fitted
            .iter()
            .fold(None::<SearchStep>, |b, x| if b.is_none_or(|b| x.cv_rms_g < b.cv_rms_g) { Some(*x) } else { b })
    else {
        return Vec::new();
    };
    let below = |x: &StaticStructure| x == &best.structure || choice::is_below(x, &best.structure);
    // The start: the simplest fitted structure under the choice (fewest unknowns, then the
    // lattice's order).
    let start =
        fitted.iter().filter(|x| below(&x.structure)).min_by_key(|x| x.structure.unknowns(g)).copied().unwrap_or(best);
    let mut path = vec![start];
    while let Some(at) = path.last().copied().filter(|at| at.structure != best.structure) {
        let next = fitted
            .iter()
            .filter(|x| below(&x.structure) && choice::is_step(&at.structure, &x.structure))
            .fold(None::<SearchStep>, |b, x| if b.is_none_or(|b| x.cv_rms_g < b.cv_rms_g) { Some(*x) } else { b });
        match next {
            Some(x) => path.push(x),
            // A part of the choice whose intermediate structures could not be fitted: the
            // choice itself is the next step.
            None => path.push(best),
        }
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{BranchMode, FitError};
    use crate::static_cal::candidates;

    /// A structure's parts as tokens, written apart from `is_step`: each step of a path must
    /// add exactly one token and keep the others.
    fn parts(st: &StaticStructure) -> Vec<String> {
        let mut p = Vec::new();
        match st.branches {
            BranchMode::Single => {}
            BranchMode::Offset => p.push("branch>=1".to_string()),
            BranchMode::Free => p.extend(["branch>=1".to_string(), "branch>=2".to_string()]),
        }
        p.extend(st.lag_tau_s.map(|t| format!("lag{t}")));
        p.extend(st.creep_tau_s.map(|t| format!("creep{t}")));
        p
    }

    /// Over random figures, with some candidates refused: the path starts at the simplest
    /// fitted structure under the choice, ends at the lowest figure, adds one part per step,
    /// each step the lowest figure among the choice's remaining parts.
    #[test]
    fn the_path_adds_one_part_at_a_time_and_ends_at_the_lowest_figure() {
        let lattice = candidates();
        let mut rng = qfa_rng::seeded(qfa_rng::stream_seed(51, qfa_rng::Stream::named("search path test"), 0));
        let mut steps_seen = 0usize;
        for _ in 0..400 {
            let cv: Vec<Vec<Result<f64, FitError>>> = lattice
                .iter()
                .map(|_| {
                    vec![if qfa_rng::uniform(&mut rng) < 0.1 {
                        Err(FitError::TooFewRows { rows: 0, unknowns: 1 })
                    } else {
                        Ok(1e-3 * (1.0 + qfa_rng::uniform(&mut rng)))
                    }]
                })
                .collect();
            let t = Tried { structures: lattice.clone(), cv: cv.clone() };
            let path = path_to(&t, 0, 16);
            let fitted: Vec<(StaticStructure, f64)> =
                lattice.iter().zip(&cv).filter_map(|(s, c)| c[0].as_ref().ok().map(|&r| (*s, r))).collect();
            let best = fitted.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
            let end = path.last().unwrap();
            assert_eq!((end.structure, end.cv_rms_g), *best);
            let goal = parts(&best.0);
            let start = &path[0];
            assert!(parts(&start.structure).iter().all(|p| goal.contains(p)), "start under the choice");
            // No fitted structure under the choice is simpler than the start.
            let n_start = parts(&start.structure).len();
            assert!(fitted
                .iter()
                .filter(|(s, _)| parts(s).iter().all(|p| goal.contains(p)))
                .all(|(s, _)| parts(s).len() >= n_start));
            for w in path.windows(2) {
                let (a, b) = (parts(&w[0].structure), parts(&w[1].structure));
                steps_seen += 1;
                if w[1].structure == best.0 && b.len() > a.len() + 1 {
                    // Only when the choice's intermediate structures were refused.
                    continue;
                }
                assert_eq!(b.len(), a.len() + 1, "{:?} -> {:?}", w[0].structure.name(), w[1].structure.name());
                assert!(a.iter().all(|p| b.contains(p)));
                // The step taken is the lowest figure among the fitted one-part additions
                // under the choice.
                let lowest = fitted
                    .iter()
                    .filter(|(s, _)| {
                        let p = parts(s);
                        p.len() == a.len() + 1 && a.iter().all(|x| p.contains(x)) && p.iter().all(|x| goal.contains(x))
                    })
                    .map(|(_, r)| *r)
                    .fold(f64::INFINITY, f64::min);
                assert_eq!(w[1].cv_rms_g, lowest);
            }
        }
        assert!(steps_seen > 400, "paths of one structure only: {steps_seen} steps");
    }
}
