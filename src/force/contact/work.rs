//! The generalised contact forces of a step and the work they do on the bodies.

/// The contact forces `f_c` of the last two evaluations, kept only on the elements they touch,
/// and their work by the trapezoid rule: `W += ½ (f_c^{n−1} + f_c^n) · (U^n − U^{n−1})`.
/// `−W` is the contact energy: what the springs store plus what friction and the release of
/// stretched springs took from the motion.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Ledger {
    nd: usize,
    now: Vec<f64>,
    before: Vec<f64>,
    touched_now: Vec<u32>,
    touched_before: Vec<u32>,
    /// Per element: bit 1 if touched now, bit 2 if touched before.
    mark: Vec<u8>,
    /// Work of the contact forces on the bodies so far (J).
    pub work: f64,
}

impl Ledger {
    pub fn new(n_elements: usize, nd: usize) -> Ledger {
        let mut ledger = Ledger {
            nd,
            now: vec![0.0; n_elements * nd],
            before: vec![0.0; n_elements * nd],
            touched_now: Vec::new(),
            touched_before: Vec::new(),
            mark: vec![0; n_elements],
            work: 0.0,
        };
        ledger.reserve();
        ledger
    }

    /// Whether `self`, read from a checkpoint, fits the ledger `fresh` of the same model: the
    /// same sizes, and every element it lists in range.
    pub fn check(&self, fresh: &Ledger) -> std::result::Result<(), String> {
        let n = fresh.mark.len();
        if self.nd != fresh.nd
            || self.now.len() != fresh.now.len()
            || self.before.len() != fresh.before.len()
            || self.mark.len() != n
            || self.touched_now.len() > n
            || self.touched_before.len() > n
            || self
                .touched_now
                .iter()
                .chain(&self.touched_before)
                .any(|&e| e as usize >= n)
        {
            return Err("its contact forces are not this model's".into());
        }
        Ok(())
    }

    /// Room to list every element as touched, so that the steps do not allocate.
    pub fn reserve(&mut self) {
        let n = self.mark.len();
        self.touched_now.reserve_exact(n);
        self.touched_before.reserve_exact(n);
    }

    /// Starts the forces of a new state; those of the last one become `f_c^{n−1}`.
    pub fn next(&mut self) {
        for &e in &self.touched_before {
            self.mark[e as usize] &= !2;
            self.before[e as usize * self.nd..(e as usize + 1) * self.nd].fill(0.0);
        }
        std::mem::swap(&mut self.now, &mut self.before);
        std::mem::swap(&mut self.touched_now, &mut self.touched_before);
        self.touched_now.clear();
        for &e in &self.touched_before {
            self.mark[e as usize] = 2;
        }
    }

    /// `f_c += q` on element `e`.
    pub fn add(&mut self, e: usize, q: &[f64]) {
        if self.mark[e] & 1 == 0 {
            self.mark[e] |= 1;
            self.touched_now.push(e as u32);
        }
        for (a, q) in self.now[e * self.nd..(e + 1) * self.nd].iter_mut().zip(q) {
            *a += q;
        }
    }

    /// Takes `q`, part of `f_c` on element `e` now, as a force that appeared at this state: it
    /// did no work over the step that led here (`f_c^{n−1} −= q`).
    pub fn unworked(&mut self, e: usize, q: &[f64]) {
        if self.mark[e] & 2 == 0 {
            self.mark[e] |= 2;
            self.touched_before.push(e as u32);
        }
        for (a, q) in self.before[e * self.nd..(e + 1) * self.nd]
            .iter_mut()
            .zip(q)
        {
            *a -= q;
        }
    }

    /// `f_c` on element `e` (zero where no contact acts).
    pub fn on(&self, e: usize) -> &[f64] {
        &self.now[e * self.nd..(e + 1) * self.nd]
    }

    /// `f −= f_c` (the contact forces join the right-hand side).
    pub fn subtract_from(&self, f: &mut [f64]) {
        for &e in &self.touched_now {
            let r = e as usize * self.nd..(e as usize + 1) * self.nd;
            for (f, q) in f[r.clone()].iter_mut().zip(&self.now[r]) {
                *f -= q;
            }
        }
    }

    /// Adds the work over the step that led here, `U^n − U^{n−1} = Δt v^{n−½}`.
    pub fn add_work(&mut self, velocity: &[f64], dt: f64) {
        let nd = self.nd;
        let mut w = 0.0;
        let mut over = |e: usize| {
            for k in e * nd..(e + 1) * nd {
                w += 0.5 * (self.before[k] + self.now[k]) * dt * velocity[k];
            }
        };
        for &e in &self.touched_now {
            over(e as usize);
        }
        for &e in &self.touched_before {
            if self.mark[e as usize] & 1 == 0 {
                over(e as usize);
            }
        }
        self.work += w;
    }
}
