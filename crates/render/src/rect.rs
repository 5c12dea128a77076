//! The rectangles of pixels a frame is cut into: what a tile is, for the renderer, its
//! running sums and the farm alike.

/// A rectangle of pixels inside the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TileRect {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

impl TileRect {
    pub fn pixel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }
}

/// Cuts `[x0, x1) x [y0, y1)` into tiles of at most `size x size`, row by row.
pub fn split_into_tiles(bounds: [u32; 4], size: u32) -> Vec<TileRect> {
    let size = size.max(1);
    let [x0, x1, y0, y1] = bounds;
    let mut tiles = Vec::new();
    let mut y = y0;
    while y < y1 {
        let h = size.min(y1 - y);
        let mut x = x0;
        while x < x1 {
            let w = size.min(x1 - x);
            tiles.push(TileRect {
                x0: x,
                y0: y,
                width: w,
                height: h,
            });
            x += w;
        }
        y += h;
    }
    tiles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_bounds_exactly_once() {
        for size in [1, 16, 37, 64, 1000] {
            let tiles = split_into_tiles([3, 103, 5, 60], size);
            let mut covered = vec![0u8; 100 * 55];
            for t in &tiles {
                assert!(t.width <= size && t.height <= size);
                for y in t.y0..t.y0 + t.height {
                    for x in t.x0..t.x0 + t.width {
                        covered[((y - 5) * 100 + (x - 3)) as usize] += 1;
                    }
                }
            }
            assert!(covered.iter().all(|&c| c == 1));
        }
    }
}
