//! A uniform grid of buckets for neighbourhood queries in the plane.

use crate::mesh::geometry::Vec2;

/// A uniform grid of buckets over a bounding box, about one bucket per item, for neighbourhood
/// queries: the mesh checks and the contact broad phase (linear instead of quadratic in the
/// number of items).
pub struct Buckets {
    lo: Vec2,
    size: Vec2,
    nx: usize,
    ny: usize,
}

impl Buckets {
    /// About `items` buckets of equal size covering the box `lo`–`hi`.
    pub fn new(lo: Vec2, hi: Vec2, items: usize) -> Buckets {
        let n = (items as f64).sqrt().ceil().max(1.0) as usize;
        let extent = (hi - lo).sup(&Vec2::repeat(f64::MIN_POSITIVE));
        let (nx, ny) = if extent.x >= extent.y {
            (n, ((n as f64 * extent.y / extent.x).ceil() as usize).max(1))
        } else {
            (((n as f64 * extent.x / extent.y).ceil() as usize).max(1), n)
        };
        Buckets {
            lo,
            size: Vec2::new(extent.x / nx as f64, extent.y / ny as f64),
            nx,
            ny,
        }
    }

    /// Number of buckets.
    pub fn count(&self) -> usize {
        self.nx * self.ny
    }

    /// The bucket `(i, j)` holding point `x` (m); points outside go to the nearest bucket.
    pub fn cell_of(&self, x: Vec2) -> (usize, usize) {
        let i = ((x.x - self.lo.x) / self.size.x)
            .floor()
            .clamp(0.0, (self.nx - 1) as f64) as usize;
        let j = ((x.y - self.lo.y) / self.size.y)
            .floor()
            .clamp(0.0, (self.ny - 1) as f64) as usize;
        (i, j)
    }

    /// The bucket of a point.
    pub fn index(&self, x: Vec2) -> usize {
        let (i, j) = self.cell_of(x);
        i + self.nx * j
    }

    /// The buckets that a box touches, widened by one bucket on each side: a query around a
    /// point on a bucket border, or within a tolerance of it, finds the items filed beside it.
    pub fn covering(&self, a: Vec2, b: Vec2) -> impl Iterator<Item = usize> + '_ {
        self.span(a, b, 1)
    }

    /// The buckets that a box touches.
    pub fn touching(&self, a: Vec2, b: Vec2) -> impl Iterator<Item = usize> + '_ {
        self.span(a, b, 0)
    }

    fn span(&self, a: Vec2, b: Vec2, widen: usize) -> impl Iterator<Item = usize> + '_ {
        let ((i0, j0), (i1, j1)) = (self.cell_of(a), self.cell_of(b));
        let (i0, j0) = (i0.saturating_sub(widen), j0.saturating_sub(widen));
        let (i1, j1) = ((i1 + widen).min(self.nx - 1), (j1 + widen).min(self.ny - 1));
        (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| i + self.nx * j))
    }
}

/// The items of each bucket in compressed form (`start[b]..start[b + 1]` indexes `items`),
/// rebuilt in place: no allocation once the buffers have grown to the problem's size.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct BucketLists {
    start: Vec<u32>,
    items: Vec<u32>,
    cursor: Vec<u32>,
}

impl BucketLists {
    /// Room for the lists of a [`Buckets`] grid made for `items` items, each filed under a few
    /// buckets: `fill` then does not allocate unless the items spread over many more.
    pub fn reserve(&mut self, items: usize) {
        let buckets = items + 4 * (items as f64).sqrt().ceil() as usize + 4;
        self.start.reserve_exact(buckets + 1);
        self.items.reserve_exact(4 * items);
        self.cursor.reserve_exact(buckets);
    }

    /// Files item `i` under every bucket that its box `boxes(i)` touches (query with
    /// [`Buckets::covering`]).
    pub fn fill(&mut self, grid: &Buckets, n_items: usize, boxes: impl Fn(usize) -> (Vec2, Vec2)) {
        self.start.clear();
        self.start.resize(grid.count() + 1, 0);
        for i in 0..n_items {
            let (a, b) = boxes(i);
            for k in grid.touching(a, b) {
                self.start[k + 1] += 1;
            }
        }
        for k in 0..grid.count() {
            self.start[k + 1] += self.start[k];
        }
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.start[..grid.count()]);
        self.items.clear();
        self.items.resize(self.start[grid.count()] as usize, 0);
        for i in 0..n_items {
            let (a, b) = boxes(i);
            for k in grid.touching(a, b) {
                self.items[self.cursor[k] as usize] = i as u32;
                self.cursor[k] += 1;
            }
        }
    }

    /// The items filed under bucket `k`.
    pub fn bucket(&self, k: usize) -> &[u32] {
        &self.items[self.start[k] as usize..self.start[k + 1] as usize]
    }
}

/// Whether two boxes `(lo, hi)` meet (touching counts).
pub fn boxes_meet((alo, ahi): (Vec2, Vec2), (blo, bhi): (Vec2, Vec2)) -> bool {
    alo.x <= bhi.x && blo.x <= ahi.x && alo.y <= bhi.y && blo.y <= ahi.y
}

/// Whether any point has moved more than `half_skin` from where it was at the last rebuild of a
/// neighbour list (`anchors`): the list, built with boxes widened by twice that, may then miss a
/// pair, and must be rebuilt.
pub fn moved_beyond(points: &[Vec2], anchors: &[Vec2], half_skin: f64) -> bool {
    let limit = half_skin * half_skin;
    points
        .iter()
        .zip(anchors)
        .any(|(x, a)| (x - a).norm_squared() > limit)
}
