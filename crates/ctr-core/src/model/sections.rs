//! Breakpoints along the backbone.
//!
//! The backbone `0 <= s <= s_n` is cut at every tube tip `s_i` and at every start of an
//! exposed curved part `s_i - curved_length_i` (when it lies beyond the guide exit).
//! Between two cuts the set of tubes present and the set of curved tubes are fixed, so
//! every section has constant coefficients.

use crate::model::robot::Robot;
use crate::real::{c, Real};
use crate::MAX_TUBES;

/// How much longer the steps of a cold solve's first Newton iterations are. They bring
/// the unknowns within the coarse grid's discretisation error of the answer, which one
/// fine iteration then removes (Newton converges quadratically).
pub const COARSE_FACTOR: f64 = 4.0;

/// Most cuts a robot of [`MAX_TUBES`] tubes can need: 0, each tip, each curve start.
pub const MAX_BREAKS: usize = 2 * MAX_TUBES + 1;

/// The coefficients of one section `[start, end]`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Section<T, const N: usize> {
    pub start: T,
    pub end: T,
    /// tube present over the section (`s_i >= end`)
    pub present: [bool; N],
    /// `E I_i k_i / sum(E I present)`: tube i's share of the bending curvature, 1/mm
    /// (0 where tube i is straight or absent)
    pub a: [T; N],
    /// `E I_i k_i / (G J_i)`: torsional coupling gain of tube i, 1/mm (0 where straight)
    pub g: [T; N],
    /// number of tubes curved over the section
    pub curved: usize,
    /// the only curved tube, if exactly one is
    pub single: usize,
    /// RK4 step for this section, mm (see [`step_length`])
    pub h: T,
    /// the coarse step of a cold solve's first Newton iterations, mm
    pub h_coarse: T,
    /// tube i is curved over the section (`a[i] != 0`), and couples (`g[i] != 0`)
    pub curved_a: [bool; N],
    pub curved_g: [bool; N],
    /// `1 / sum(E I present)`, 1/(N mm^2)
    pub inv_k: T,
}

/// Sections of a configuration, in order from the guide exit to the tip.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sections<T, const N: usize> {
    pub list: [Section<T, N>; MAX_BREAKS],
    pub len: usize,
}

impl<T: Real, const N: usize> Sections<T, N> {
    /// Cuts the backbone of `robot` at feeds `s`.
    pub fn new(
        robot: &Robot<T, N>,
        s: &[T; N],
        precurvature: &[T; N],
        h_max: T,
        fraction: T,
    ) -> Self {
        let mut cuts = [T::zero(); MAX_BREAKS];
        let mut n = 1;
        let end = s[N - 1];
        for i in 0..N {
            let start_curve = s[i] - robot.tubes()[i].params().curved_length_mm;
            for cut in [s[i], start_curve] {
                if cut > T::zero() && cut <= end && n < MAX_BREAKS {
                    cuts[n] = cut;
                    n += 1;
                }
            }
        }
        // insertion sort of at most 9 values
        for i in 1..n {
            let mut j = i;
            while j > 0 && cuts[j - 1] > cuts[j] {
                cuts.swap(j - 1, j);
                j -= 1;
            }
        }
        let empty = Section {
            start: T::zero(),
            end: T::zero(),
            present: [false; N],
            a: [T::zero(); N],
            g: [T::zero(); N],
            curved: 0,
            single: 0,
            h: T::zero(),
            h_coarse: T::zero(),
            curved_a: [false; N],
            curved_g: [false; N],
            inv_k: T::zero(),
        };
        // built in place (the list is ~1 KB: a copy on return would cost as much as
        // the cutting)
        let mut out = Sections {
            list: [empty; MAX_BREAKS],
            len: 0,
        };
        for k in 0..n.saturating_sub(1) {
            let (a, b) = (cuts[k], cuts[k + 1]);
            if b <= a {
                continue;
            }
            let mut sec = empty;
            sec.start = a;
            sec.end = b;
            let mut stiff = T::zero();
            for i in 0..N {
                sec.present[i] = s[i] >= b;
                if sec.present[i] {
                    stiff += robot.tubes()[i].bending_stiffness_nmm2();
                }
            }
            sec.inv_k = T::one() / stiff;
            for i in 0..N {
                let tube = &robot.tubes()[i];
                let curve_start = s[i] - tube.params().curved_length_mm;
                let k_i = precurvature[i];
                if sec.present[i] && a >= curve_start && k_i != T::zero() {
                    let ek = tube.bending_stiffness_nmm2() * k_i;
                    sec.a[i] = ek / stiff;
                    sec.g[i] = ek / tube.torsional_stiffness_nmm2();
                    sec.curved_a[i] = sec.a[i] != T::zero();
                    sec.curved_g[i] = sec.g[i] != T::zero();
                    sec.curved += 1;
                    sec.single = i;
                }
            }
            sec.h = step_length(&sec, h_max, fraction);
            sec.h_coarse = step_length(&sec, h_max * c(COARSE_FACTOR), fraction * c(COARSE_FACTOR));

            out.list[out.len] = sec;
            out.len += 1;
        }
        out
    }
}

/// The RK4 step of a section: `fraction` of its shortest length scale, at most `h_max`.
///
/// Two length scales set the error of a step: the radius of the bending curvature,
/// `1 / sum|a_l|`, and the wavelength of the twist coupling, `1 / sqrt(c)` with
/// `c = max_j |g_j| sum_l |a_l|` (for two tubes the `c` of the seed's
/// `beta'' = c sin beta`). The local error of both RK4 and the Magnus pose step scales
/// as `(h / scale)^5`, so a fixed fraction gives the same accuracy on any robot.
fn step_length<T: Real, const N: usize>(sec: &Section<T, N>, h_max: T, fraction: T) -> T {
    let mut bend = T::zero();
    let mut gain = T::zero();
    for i in 0..N {
        bend += sec.a[i].abs();
        gain = gain.max(sec.g[i].abs());
    }
    let rate = bend.max((gain * bend).sqrt());
    if rate > T::zero() {
        h_max.min(fraction / rate)
    } else {
        h_max
    }
}
