//! The one-dimensional and two-dimensional searches of discovery's nonlinear parameters.

/// Golden-section minimum of `f` on `[a, b]`.
pub(crate) fn golden(mut f: impl FnMut(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

/// Nelder–Mead in 2-D from `x0` with initial steps `step`.
pub(crate) fn nelder_mead2(
    mut f: impl FnMut([f64; 2]) -> f64,
    x0: [f64; 2],
    step: [f64; 2],
    iters: usize,
) -> ([f64; 2], f64) {
    let mut s = [x0, [x0[0] + step[0], x0[1]], [x0[0], x0[1] + step[1]]];
    let mut v = [f(s[0]), f(s[1]), f(s[2])];
    let lerp = |a: [f64; 2], b: [f64; 2], t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    for _ in 0..iters {
        let mut idx = [0, 1, 2];
        idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        s = [s[idx[0]], s[idx[1]], s[idx[2]]];
        v = [v[idx[0]], v[idx[1]], v[idx[2]]];
        let c = lerp(s[0], s[1], 0.5);
        let xr = lerp(s[2], c, 2.0);
        let fr = f(xr);
        if fr < v[0] {
            let xe = lerp(s[2], c, 3.0);
            let fe = f(xe);
            if fe < fr {
                (s[2], v[2]) = (xe, fe);
            } else {
                (s[2], v[2]) = (xr, fr);
            }
        } else if fr < v[1] {
            (s[2], v[2]) = (xr, fr);
        } else {
            let xc = lerp(s[2], c, 0.5);
            let fcv = f(xc);
            if fcv < v[2] {
                (s[2], v[2]) = (xc, fcv);
            } else {
                for i in 1..3 {
                    s[i] = lerp(s[0], s[i], 0.5);
                    v[i] = f(s[i]);
                }
            }
        }
    }
    let b = (0..3).min_by(|&i, &j| v[i].total_cmp(&v[j])).unwrap_or(0);
    (s[b], v[b])
}
