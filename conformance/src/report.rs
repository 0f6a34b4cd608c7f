//! A case's verdict on one backend and the report of a suite run.

use std::fmt::Write as _;

/// Outcome of one case on one backend.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// The case's physical assertion held; `metric` is what was measured.
    Pass {
        /// Measured value, e.g. `relMSE 0.003`.
        metric: String,
    },
    /// The assertion failed.
    Fail {
        /// What was measured and what was expected.
        detail: String,
    },
    /// Failed as expected on this backend; an expectation needs a written reason.
    ExpectedFail {
        /// Why this backend cannot pass the case.
        reason: String,
        /// What the case measured this time (empty when it did not run).
        measured: String,
    },
    /// Not run: data the case needs (`../shared/scenes`) is absent and env `CI` is not set
    /// (with `CI` set the same situation is a [`Verdict::Fail`]).
    Skipped {
        /// What is missing.
        reason: String,
    },
    /// Not run because the case does not apply to this backend: it needs a capability the
    /// backend does not offer (the WGSL-twin cases on a backend without a
    /// [`crate::KernelRunner`], such as cpu, which runs the Rust reference itself). Neither a
    /// pass nor a failure, with or without `CI`.
    NotApplicable {
        /// Why the case does not apply.
        reason: String,
    },
}

impl Verdict {
    /// `true` unless the case failed unexpectedly.
    pub fn is_ok(&self) -> bool {
        !matches!(self, Verdict::Fail { .. })
    }

    fn cell(&self) -> String {
        match self {
            Verdict::Pass { metric } => format!("pass ({metric})"),
            Verdict::Fail { detail } => format!("**FAIL** ({detail})"),
            Verdict::ExpectedFail { reason, measured } if measured.is_empty() => {
                format!("xfail ({reason})")
            }
            Verdict::ExpectedFail { reason, measured } => {
                format!("xfail ({reason}; measured: {measured})")
            }
            Verdict::Skipped { reason } => format!("**SKIPPED** ({reason})"),
            Verdict::NotApplicable { reason } => format!("n/a ({reason})"),
        }
    }
}

/// A case × backend table of verdicts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Report {
    backends: Vec<String>,
    rows: Vec<(String, Vec<Option<Verdict>>)>,
}

impl Report {
    /// Records `verdict` for `case` on `backend`.
    pub fn record(&mut self, case: &str, backend: &str, verdict: Verdict) {
        let col = match self.backends.iter().position(|b| b == backend) {
            Some(c) => c,
            None => {
                self.backends.push(backend.to_owned());
                for (_, cells) in &mut self.rows {
                    cells.push(None);
                }
                self.backends.len() - 1
            }
        };
        let row = match self.rows.iter().position(|(c, _)| c == case) {
            Some(r) => r,
            None => {
                self.rows
                    .push((case.to_owned(), vec![None; self.backends.len()]));
                self.rows.len() - 1
            }
        };
        self.rows[row].1[col] = Some(verdict);
    }

    /// The verdict of the row `case` (a [`crate::Case::title`], or [`crate::suite::AVAILABILITY_ROW`])
    /// on `backend`; `None` when that cell did not run.
    pub fn get(&self, case: &str, backend: &str) -> Option<&Verdict> {
        let col = self.backends.iter().position(|b| b == backend)?;
        let (_, cells) = self.rows.iter().find(|(c, _)| c == case)?;
        cells.get(col)?.as_ref()
    }

    /// `true` when no verdict is an unexpected failure.
    pub fn all_ok(&self) -> bool {
        self.rows
            .iter()
            .flat_map(|(_, cells)| cells.iter().flatten())
            .all(Verdict::is_ok)
    }

    /// Number of [`Verdict::Skipped`] cells.
    pub fn skipped(&self) -> usize {
        self.count(|v| matches!(v, Verdict::Skipped { .. }))
    }

    /// Number of [`Verdict::NotApplicable`] cells.
    pub fn not_applicable(&self) -> usize {
        self.count(|v| matches!(v, Verdict::NotApplicable { .. }))
    }

    /// Number of [`Verdict::Pass`] cells.
    pub fn passed(&self) -> usize {
        self.count(|v| matches!(v, Verdict::Pass { .. }))
    }

    fn count(&self, pred: impl Fn(&Verdict) -> bool) -> usize {
        self.rows
            .iter()
            .flat_map(|(_, cells)| cells.iter().flatten())
            .filter(|v| pred(v))
            .count()
    }

    /// The table as GitHub-flavoured Markdown (cells that did not run show `–`).
    pub fn to_markdown(&self) -> String {
        let mut s = String::from("| case |");
        for b in &self.backends {
            let _ = write!(s, " {b} |");
        }
        s.push_str("\n|---|");
        s.push_str(&"---|".repeat(self.backends.len()));
        s.push('\n');
        for (case, cells) in &self.rows {
            let _ = write!(s, "| {case} |");
            for c in cells {
                let _ = write!(
                    s,
                    " {} |",
                    c.as_ref().map_or_else(|| "–".to_owned(), Verdict::cell)
                );
            }
            s.push('\n');
        }
        s
    }
}
