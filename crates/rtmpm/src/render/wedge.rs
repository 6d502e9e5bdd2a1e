//! `rtmpm render OUTDIR` of a batch run (a folder with `batch.csv`): one picture per frame with
//! every world side by side in a grid, each world's swept values written under it
//! (`wedge_NNNNN.png`, `wedge.gif`). A frozen world shows its last frame, marked.

use super::cmd::{RenderArgs, ply_frames, render_cmd};
use super::*;
use rtmpm_render::Image;
use rtmpm_render::text::{draw_text, text_height, text_width};

/// Largest side of a wedge picture (pixels), as for `--size`: a grid of more worlds than tiles
/// of 64 pixels fit is refused.
const MAX_WEDGE_SIDE: u32 = 8192;

/// One world of the batch, as `batch.csv` lists it.
struct WorldRow {
    folder: PathBuf,
    label: String,
    frozen: bool,
}

/// The rows of `batch.csv` (written by `rtmpm run` of a batch).
fn read_batch_csv(dir: &Path) -> Result<Vec<WorldRow>> {
    let path = dir.join("batch.csv");
    let text = rtmpm_io::limits::read_text_bounded(&path, 64 << 20, "batch.csv")?;
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let cols = split_csv(line);
        if cols.len() < 4 {
            bail!(
                "{}:{}: expected world,folder,label,status,...; the file is not rtmpm's",
                path.display(),
                n + 1
            );
        }
        let folder = dir.join(&cols[1]);
        if cols[1].contains(['/', '\\']) || cols[1].starts_with('.') || !folder.is_dir() {
            bail!(
                "{}:{}: world folder `{}` is not a folder of {}",
                path.display(),
                n + 1,
                cols[1],
                dir.display()
            );
        }
        rows.push(WorldRow {
            folder,
            label: cols[2].clone(),
            frozen: cols[3].starts_with("frozen"),
        });
    }
    if rows.is_empty() {
        bail!("{} lists no world", path.display());
    }
    Ok(rows)
}

/// The fields of a CSV line (quoted fields may hold commas and doubled quotes).
fn split_csv(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut field = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => {
                *out.last_mut().expect("one field at least") = std::mem::take(&mut field);
                out.push(String::new());
            }
            (c, _) => field.push(c),
        }
    }
    *out.last_mut().expect("one field at least") = field;
    out
}

/// The caption of a world: each swept value by its field's last name
/// (`material[0].yield_stress = 150` is written `YIELD_STRESS = 150`).
fn caption(label: &str) -> String {
    label
        .split(", ")
        .map(|part| match part.split_once(" = ") {
            Some((path, v)) => format!("{} = {v}", path.rsplit('.').next().unwrap_or(path)),
            None => part.to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Columns and rows of a grid of `n` pictures, about as wide as 16:9 tiles make it square.
fn grid(n: usize) -> (usize, usize) {
    let cols = (n as f64).sqrt().ceil().max(1.0) as usize;
    (cols, n.div_ceil(cols))
}

/// `rtmpm render`: the wedge of a batch run's folder (it holds `batch.csv`), else the frames
/// of a run ([`render_cmd`]).
pub fn dispatch(args: RenderArgs) -> Result<()> {
    match &args.outdir {
        Some(dir) if !args.bench && dir.join("batch.csv").is_file() => render_wedge(&args, dir),
        _ => render_cmd(args),
    }
}

/// Render the wedge of the batch run in `dir`.
fn render_wedge(args: &RenderArgs, dir: &Path) -> Result<()> {
    let _lock = rtmpm_driver::outdir::OutDir::lock(dir, "rtmpm render")?;
    let worlds = read_batch_csv(dir)?;
    // The picture's size first: before the worlds' frames are listed and read.
    let tiles = Tiles::of(args, &worlds)?;
    let frames: Vec<Vec<(u64, PathBuf)>> = worlds
        .iter()
        .map(|w| ply_frames(&w.folder))
        .collect::<Result<_>>()?;
    let Some(numbers) = frames.iter().map(|f| f.len()).max().filter(|&n| n > 0) else {
        bail!(
            "no frame_NNNNN.ply files in the world folders of {} (the batch must write PLY \
             frames: [output] formats = [\"ply\", ...])",
            dir.display()
        );
    };
    let longest = frames
        .iter()
        .find(|f| f.len() == numbers)
        .cloned()
        .unwrap_or_default();
    let scene = match &args.scene {
        // A batch's scene file gives its scene as written (the worlds' common settings).
        Some(p) => Some(rtmpm_scene::BatchScene::from_file(p)?.base),
        None => None,
    };
    let color_by = args
        .view
        .color_by
        .or(scene.as_ref().and_then(|s| s.render.color_by))
        .unwrap_or_default();
    let read = |path: &Path, num: u64| -> Result<FrameJob> {
        let d = read_ply(path).with_context(|| format!("reading {}", path.display()))?;
        FrameJob::from_ply(num, &d, color_by, path)
    };
    // One camera for every world: the scene's box, else the first frames' bounding box.
    let first: Vec<FrameJob> = frames
        .iter()
        .filter_map(|f| f.first())
        .map(|(num, p)| read(p, *num))
        .collect::<Result<_>>()?;
    let radius = estimate_radius(&first[0].positions);
    let (bounds, floor) = match &scene {
        Some(s) => scene_bounds(s),
        None => bounds_around(&first, radius),
    };
    let (cols, rows, tile_w, tile_h, strip) = (
        tiles.cols,
        tiles.rows,
        tiles.tile_w,
        tiles.tile_h,
        tiles.strip,
    );
    let mut view = args.view.clone();
    view.size = Some(Size(tile_w, tile_h));
    let mut opts = resolve(&view, scene.as_ref(), bounds, floor, radius)?;
    let fps = args
        .fps
        .or(scene.as_ref().map(|s| s.time.fps))
        .unwrap_or(30.0);
    let gif_size = args.view.gif_size.unwrap_or(Size(
        (tile_w * cols as u32).min(960),
        ((tile_h + strip) * rows as u32) * (tile_w * cols as u32).min(960) / (tile_w * cols as u32),
    ));
    let mut gif = (!args.view.no_movie)
        .then(|| GifMovie::new(gif_size.0, gif_size.1, fps))
        .transpose()?;
    eprintln!(
        "rendering the wedge of {} worlds ({cols} x {rows}), {numbers} frames of {} at {tile_w}x{tile_h} a world",
        worlds.len(),
        dir.display()
    );
    for (k, (num, _)) in longest.iter().enumerate() {
        let mut img = Image::new(
            tile_w * cols as u32,
            (tile_h + strip) * rows as u32,
            [24, 24, 28],
        );
        for (w, world) in worlds.iter().enumerate() {
            // A frozen world shows its last frame.
            let Some((fnum, path)) = frames[w].get(k).or(frames[w].last()) else {
                continue;
            };
            let job = read(path, *fnum)?;
            opts.label = None;
            let tile = render(
                &RenderInput {
                    positions: &job.positions,
                    material: &job.material,
                    field: job.field.as_deref(),
                    surface: None,
                },
                &opts,
            )
            .with_context(|| format!("rendering {}", path.display()))?;
            let stopped = frames[w].get(k).is_none() || (world.frozen && k + 1 >= frames[w].len());
            let mut text = caption(&world.label);
            if stopped && world.frozen {
                text = format!("{text} (FROZEN)");
            }
            tiles.place(&mut img, w, &tile, &text);
        }
        let path = dir.join(format!("wedge_{num:05}.png"));
        img.write_png(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        if let Some(g) = gif.as_mut() {
            g.add(&img).context("adding a frame to the GIF")?;
        }
    }
    finish_movie(gif, dir, numbers, worlds.len())
}

/// Write the wedge's GIF (where one is made) into `dir`, and say what was written: `numbers`
/// pictures of `worlds` worlds.
fn finish_movie(gif: Option<GifMovie>, dir: &Path, numbers: usize, worlds: usize) -> Result<()> {
    let mut summary = format!(
        "{numbers} wedge pictures of {} worlds: {}/wedge_NNNNN.png",
        worlds,
        dir.display()
    );
    if let Some(g) = gif {
        let path = dir.join("wedge.gif");
        g.finish(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        summary.push_str(&format!(", {}", path.display()));
    }
    println!("{summary}");
    Ok(())
}

/// The camera's box when there is no scene: twice the widest extent of the first frames'
/// particles around them (room to slump and spread), and the floor under them.
fn bounds_around(first: &[FrameJob], radius: f32) -> ((Vec3, Vec3), f32) {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in first
        .iter()
        .flat_map(|j| &j.positions)
        .filter(|p| p.is_finite())
    {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if !lo.is_finite() {
        (lo, hi) = (Vec3::ZERO, Vec3::ONE);
    }
    // Room to slump and spread: twice the widest extent around the bodies.
    let c = 0.5 * (lo + hi);
    let half = Vec3::splat((hi - lo).max_element()) + Vec3::splat(radius);
    (
        (
            Vec3::new(c.x - half.x, lo.y - radius, c.z - half.z),
            c + half,
        ),
        lo.y - radius,
    )
}

/// The wedge picture's grid: `cols` x `rows` tiles of `tile_w` x `tile_h` pixels, each with a
/// caption strip of `strip` pixels below it, written at `scale` times the font's size.
struct Tiles {
    cols: usize,
    rows: usize,
    tile_w: u32,
    tile_h: u32,
    scale: u32,
    strip: u32,
}

impl Tiles {
    /// The grid of `worlds`: the image's width (default 1280) over the columns, 16:9 tiles,
    /// captions twice the font's size where the longest fits in a tile.
    fn of(args: &RenderArgs, worlds: &[WorldRow]) -> Result<Tiles> {
        let (cols, rows) = grid(worlds.len());
        // Tiles: the image's width (default 1280) over the columns, 16:9, a caption strip below.
        let width = args.view.size.map_or(1280, |s| s.0).max(64 * cols as u32);
        let tile_w = width / cols as u32;
        let tile_h = (tile_w * 9 / 16).max(16);
        // Captions twice the font's size where the longest fits in a tile.
        let longest_caption = worlds
            .iter()
            .map(|w| text_width(&caption(&w.label), 2))
            .max()
            .unwrap_or(0);
        let scale = if longest_caption + 8 <= tile_w { 2 } else { 1 };
        let strip = text_height(scale) + 6 * scale;
        let height = (tile_h + strip) as u64 * rows as u64;
        if width > MAX_WEDGE_SIDE || height > MAX_WEDGE_SIDE as u64 {
            bail!(
                "{} worlds make a grid of {cols} x {rows} tiles, a picture of {width}x{height} \
                 pixels, more than the {MAX_WEDGE_SIDE} a side a picture may have\n  fix: render \
                 one world's folder (rtmpm render OUT/world_NNN) or a batch of fewer worlds",
                worlds.len()
            );
        }
        Ok(Tiles {
            cols,
            rows,
            tile_w,
            tile_h,
            scale,
            strip,
        })
    }

    /// Copy world `w`'s picture `tile` into its place in `img`, with its caption `text`
    /// centred in the strip below it.
    fn place(&self, img: &mut Image, w: usize, tile: &Image, text: &str) {
        let (tile_w, tile_h, scale) = (self.tile_w, self.tile_h, self.scale);
        let (x0, y0) = (
            (w % self.cols) as u32 * tile_w,
            (w / self.cols) as u32 * (tile_h + self.strip),
        );
        blit(img, tile, x0, y0);
        let tx = x0 as i32 + (tile_w as i32 - text_width(text, scale) as i32).max(0) / 2;
        let ty = (y0 + tile_h + 3 * scale) as i32;
        draw_text(img, tx, ty, text, scale, [235, 235, 235]);
    }
}

/// Copy `tile` into `img` with its top-left corner at `(x0, y0)` (clipped).
fn blit(img: &mut Image, tile: &Image, x0: u32, y0: u32) {
    for y in 0..tile.height.min(img.height.saturating_sub(y0)) {
        let n = tile.width.min(img.width.saturating_sub(x0)) as usize * 3;
        let src = 3 * (y * tile.width) as usize;
        let dst = 3 * ((y0 + y) * img.width + x0) as usize;
        img.rgb[dst..dst + n].copy_from_slice(&tile.rgb[src..src + n]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn captions_name_the_field_and_its_value() {
        assert_eq!(
            caption("material[0].yield_stress = 150"),
            "yield_stress = 150"
        );
        assert_eq!(
            caption("gravity[1] = -5, body[0].velocity = [1, 0, 0]"),
            "gravity[1] = -5, velocity = [1, 0, 0]"
        );
        assert_eq!(caption("world 3"), "world 3");
    }

    #[test]
    fn csv_fields_keep_quoted_commas() {
        assert_eq!(
            split_csv("1,world_001,\"a = 1, b = [1, 2]\",running,3,40"),
            vec!["1", "world_001", "a = 1, b = [1, 2]", "running", "3", "40"]
        );
        assert_eq!(split_csv("\"say \"\"hi\"\"\",x"), vec!["say \"hi\"", "x"]);
    }

    #[test]
    fn grids_are_about_square() {
        assert_eq!(grid(16), (4, 4));
        assert_eq!(grid(5), (3, 2));
        assert_eq!(grid(1), (1, 1));
    }

    #[test]
    fn blit_copies_inside_and_clips_outside() {
        let mut img = Image::new(4, 3, [0, 0, 0]);
        let tile = Image::new(2, 2, [9, 9, 9]);
        blit(&mut img, &tile, 3, 2);
        assert_eq!(img.pixel(3, 2), [9, 9, 9]);
        assert_eq!(img.pixel(2, 2), [0, 0, 0]);
        assert_eq!(img.pixel(3, 1), [0, 0, 0]);
    }
}
