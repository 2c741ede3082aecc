//! Frame step `film`, its storage: images kept a row at a time as runs of one channel,
//! the layout every filter pass (`temporal`, `atrous`, the remodulation in `denoise`)
//! reads and writes, so one pass's output is the next pass's input without a copy.

use std::marker::PhantomData;

use glam::Vec3;
use rayon::prelude::*;

/// Rows per parallel job in every filter pass: tall enough to amortise the handoff and
/// the temporal pass's halo (a row either side of its band), short enough to share out
/// evenly over the threads. With the passes run one at a time, 4 and 16 both measured
/// slower than 8 (first-light at 640 x 360, half scale, two threads: temporal + spatial
/// 2.04 -> 2.13 and 2.02 -> 2.13 ms); chained (film/chain.rs), 16 measured the same as 8
/// (1.652 against 1.668 ms, 4 alternated pairs).
pub(crate) const BAND_ROWS: usize = 8;

/// Images stored a row at a time, each row as `PLANES` consecutive runs of `width` floats
/// (row y's plane k starts at (y PLANES + k) width). A tap reads a run of contiguous lanes
/// per plane, so a row's taps vectorise; a band of rows is one slice, so bands are written
/// in parallel. (Pixels as structs cost 29 ns a tap at 480 x 270; these planes, 1.2.)
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowPlanes<const PLANES: usize> {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl<const PLANES: usize> RowPlanes<PLANES> {
    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Sizes the image, keeping the allocation (a fresh 4 MB buffer a frame cost more in
    /// page faults than a wavelet pass).
    pub fn resize(&mut self, width: usize, height: usize) {
        self.width = width;
        self.height = height;
        self.data.resize(width * height * PLANES, 0.0);
    }

    /// Row `y` of plane `plane`.
    #[inline(always)]
    pub fn row(&self, y: usize, plane: usize) -> &[f32] {
        let start = (y * PLANES + plane) * self.width;
        &self.data[start..start + self.width]
    }

    /// Row `y` of plane `plane`, to write.
    #[inline(always)]
    pub fn row_mut(&mut self, y: usize, plane: usize) -> &mut [f32] {
        let start = (y * PLANES + plane) * self.width;
        &mut self.data[start..start + self.width]
    }

    /// Pixel (x, y)'s value in every plane, in plane order.
    pub fn pixel(&self, x: usize, y: usize) -> [f32; PLANES] {
        let mut values = [0.0; PLANES];
        let start = y * PLANES * self.width + x;
        for (value, stored) in values
            .iter_mut()
            .zip(self.data[start..].iter().step_by(self.width.max(1)))
        {
            *value = *stored;
        }
        values
    }

    /// Sets pixel (x, y) in every plane (one slice a pixel, not one a plane: the render
    /// sets every guide pixel of a frame this way, serially).
    pub fn set_pixel(&mut self, x: usize, y: usize, values: [f32; PLANES]) {
        let start = y * PLANES * self.width + x;
        for (stored, value) in self.data[start..]
            .iter_mut()
            .step_by(self.width.max(1))
            .zip(values)
        {
            *stored = value;
        }
    }

    /// Every row of every plane, for threads that each write runs of their own
    /// (`SharedRuns`; run (y PLANES + k) width + x is row y of plane k from x).
    pub(crate) fn shared_runs(&mut self) -> SharedRuns<'_, f32> {
        SharedRuns::new(&mut self.data)
    }

    /// Bands of `BAND_ROWS` rows, for parallel writing: (first row, its planes).
    pub fn bands_mut(&mut self) -> impl IndexedParallelIterator<Item = (usize, &mut [f32])> {
        let band = self.width * PLANES * BAND_ROWS;
        self.data
            .par_chunks_mut(band.max(1))
            .enumerate()
            .map(|(index, data)| (index * BAND_ROWS, data))
    }
}

/// A buffer that many threads write at once, each through runs of it no other thread
/// touches: the render's tiles write their rectangles of the film and the guides straight
/// in, a run per row (and plane), while the pixels are still in their caches.
pub(crate) struct SharedRuns<'a, T> {
    start: *mut T,
    len: usize,
    /// Borrowed mutably for as long as any run can be handed out.
    _buffer: PhantomData<&'a mut [T]>,
}

// SAFETY: a `SharedRuns` only hands out runs through `run`, whose callers promise that no
// two live runs overlap, so sharing it between threads shares no element.
unsafe impl<T: Send> Sync for SharedRuns<'_, T> {}
// SAFETY: as for `Sync`; the buffer itself is borrowed for `'a`.
unsafe impl<T: Send> Send for SharedRuns<'_, T> {}

impl<'a, T> SharedRuns<'a, T> {
    pub(crate) fn new(buffer: &'a mut [T]) -> SharedRuns<'a, T> {
        SharedRuns {
            start: buffer.as_mut_ptr(),
            len: buffer.len(),
            _buffer: PhantomData,
        }
    }

    /// The `len` elements from `first` (panics past the buffer's end).
    ///
    /// # Safety
    /// No other run the caller or another thread holds may overlap this one while it lives.
    #[allow(clippy::mut_from_ref)]
    #[inline(always)]
    pub(crate) unsafe fn run(&self, first: usize, len: usize) -> &mut [T] {
        assert!(
            first <= self.len && len <= self.len - first,
            "run {first}+{len} past a buffer of {}",
            self.len
        );
        // SAFETY: in bounds (asserted); not aliased (the caller's promise).
        unsafe { std::slice::from_raw_parts_mut(self.start.add(first), len) }
    }

    /// The `len` elements from `first`, to read (panics past the buffer's end).
    ///
    /// # Safety
    /// No run another thread holds may overlap this one while it lives.
    #[inline(always)]
    pub(crate) unsafe fn read(&self, first: usize, len: usize) -> &[T] {
        assert!(
            first <= self.len && len <= self.len - first,
            "run {first}+{len} past a buffer of {}",
            self.len
        );
        // SAFETY: in bounds (asserted); not written meanwhile (the caller's promise).
        unsafe { std::slice::from_raw_parts(self.start.add(first), len) }
    }
}

impl<'a> SharedRuns<'a, f32> {
    /// Rows of the buffer as `width`-wide runs of `PLANES` planes (`RowPlanes`' layout),
    /// to read while other threads write other rows through this `SharedRuns`.
    ///
    /// # Safety
    /// While the view lives, every row read through it has been written (or holds what it
    /// held before), and no run covering a row is held while a slice of that row lives.
    pub(crate) unsafe fn rows<const PLANES: usize>(
        &self,
        width: usize,
        height: usize,
    ) -> PlaneRows<'_, PLANES> {
        assert!(
            width * height * PLANES <= self.len,
            "{height} rows of {PLANES} x {width} past a buffer of {}",
            self.len
        );
        PlaneRows {
            start: self.start,
            width,
            height,
            _data: PhantomData,
        }
    }
}

/// Rows of an image in `RowPlanes`' layout, which other threads may be writing elsewhere
/// while these are read (a chain of passes, film/chain.rs): each row read is a slice of
/// its own, so reading one row borrows nothing of the rows being written.
#[derive(Clone, Copy)]
pub(crate) struct PlaneRows<'a, const PLANES: usize> {
    start: *const f32,
    width: usize,
    height: usize,
    _data: PhantomData<&'a [f32]>,
}

// SAFETY: a `PlaneRows` only reads, and only rows no thread writes meanwhile (the promise
// made when it was made from a `SharedRuns`; one made from a shared borrow has no writers).
unsafe impl<const PLANES: usize> Sync for PlaneRows<'_, PLANES> {}
// SAFETY: as for `Sync`.
unsafe impl<const PLANES: usize> Send for PlaneRows<'_, PLANES> {}

impl<'a, const PLANES: usize> PlaneRows<'a, PLANES> {
    /// Every row of `planes`, which nothing writes while they are borrowed.
    pub(crate) fn of(planes: &'a RowPlanes<PLANES>) -> PlaneRows<'a, PLANES> {
        PlaneRows {
            start: planes.data.as_ptr(),
            width: planes.width,
            height: planes.height,
            _data: PhantomData,
        }
    }

    pub(crate) fn width(&self) -> usize {
        self.width
    }

    pub(crate) fn height(&self) -> usize {
        self.height
    }

    /// Row `y` of plane `plane`.
    #[inline(always)]
    pub(crate) fn row(&self, y: usize, plane: usize) -> &[f32] {
        assert!(
            y < self.height && plane < PLANES,
            "row {y} of plane {plane} past {} rows of {PLANES}",
            self.height
        );
        // SAFETY: inside the buffer (the constructors checked its length); no thread
        // writes the row while it is read (their contract).
        unsafe {
            std::slice::from_raw_parts(
                self.start.add((y * PLANES + plane) * self.width),
                self.width,
            )
        }
    }
}

/// Signal planes: demodulated illumination and its luminance variance.
pub const RED: usize = 0;
pub const GREEN: usize = 1;
pub const BLUE: usize = 2;
pub const VARIANCE: usize = 3;
pub const SIGNAL_PLANES: usize = 4;

/// What the filters pass along: illumination in three planes and its luminance variance.
pub type SignalPlanes = RowPlanes<SIGNAL_PLANES>;

impl SignalPlanes {
    /// Pixel `index`'s (row-major) illumination.
    pub fn illumination(&self, index: usize) -> Vec3 {
        let (x, y) = (index % self.width, index / self.width);
        Vec3::new(
            self.row(y, RED)[x],
            self.row(y, GREEN)[x],
            self.row(y, BLUE)[x],
        )
    }

    /// The illumination of every pixel, row-major.
    pub fn colours(&self) -> Vec<Vec3> {
        // Collected, not zero-filled then written: glibc serves a freed multi-megabyte
        // buffer again from the heap, and calloc then clears it byte by byte.
        (0..self.width * self.height)
            .into_par_iter()
            .map(|index| self.illumination(index))
            .collect()
    }

    /// Planes holding `illumination` and `variance` (row-major, `width` across).
    pub fn from_pixels(illumination: &[Vec3], variance: &[f32], width: usize) -> SignalPlanes {
        let height = illumination.len() / width.max(1);
        let mut planes = SignalPlanes::default();
        planes.resize(width, height);
        planes.bands_mut().for_each(|(first_row, rows)| {
            for (row_in_band, row) in rows.chunks_mut(width * SIGNAL_PLANES).enumerate() {
                let start = (first_row + row_in_band) * width;
                for x in 0..width {
                    let c = illumination[start + x];
                    row[RED * width + x] = c.x;
                    row[GREEN * width + x] = c.y;
                    row[BLUE * width + x] = c.z;
                    row[VARIANCE * width + x] = variance[start + x];
                }
            }
        });
        planes
    }
}
