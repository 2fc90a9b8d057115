//! The PNG: a scene's SVG rendered by `resvg` with DejaVu Sans, encoded by `png`.

use std::path::Path;

use super::{to_svg, Scene};

/// The PNG is drawn at this many pixels per SVG unit.
pub(super) const PNG_SCALE: f32 = 2.0;

/// The font database: DejaVu Sans, regular and bold, from the `dejavu` crate.
fn fonts() -> std::sync::Arc<resvg::usvg::fontdb::Database> {
    static DB: std::sync::OnceLock<std::sync::Arc<resvg::usvg::fontdb::Database>> =
        std::sync::OnceLock::new();
    DB.get_or_init(|| {
        let mut db = resvg::usvg::fontdb::Database::new();
        db.load_font_data(dejavu::sans::regular().to_vec());
        db.load_font_data(dejavu::sans::bold().to_vec());
        db.set_sans_serif_family("DejaVu Sans");
        std::sync::Arc::new(db)
    })
    .clone()
}

/// Renders the scene's SVG: width, height and RGB pixels on white.
pub fn rasterise(sc: &Scene) -> std::io::Result<(u32, u32, Vec<u8>)> {
    use resvg::{tiny_skia, usvg};
    let opt = usvg::Options {
        fontdb: fonts(),
        ..Default::default()
    };
    let tree = usvg::Tree::from_str(&to_svg(sc), &opt).map_err(std::io::Error::other)?;
    let (w, h) = (
        (sc.w as f32 * PNG_SCALE).round() as u32,
        (sc.h as f32 * PNG_SCALE).round() as u32,
    );
    let mut pixmap = tiny_skia::Pixmap::new(w, h)
        .ok_or_else(|| std::io::Error::other(format!("cannot draw a {w}×{h} image")))?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(
        &tree,
        tiny_skia::Transform::from_scale(PNG_SCALE, PNG_SCALE),
        &mut pixmap.as_mut(),
    );
    // Opaque on white: premultiplied RGBA is plain RGB.
    let rgb = pixmap
        .data()
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    Ok((w, h, rgb))
}

/// Writes the scene as a PNG file, whole or not at all.
pub fn write_png(sc: &Scene, path: &Path) -> std::io::Result<()> {
    let (w, h, px) = rasterise(sc)?;
    let mut bytes = Vec::new();
    encode_png(w, h, &px, &mut bytes)?;
    tiltsim_rundir::files::write_atomic(path, bytes)
}

fn encode_png(w: u32, h: u32, px: &[u8], out: &mut Vec<u8>) -> std::io::Result<()> {
    let mut enc = png::Encoder::new(out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut wr = enc.write_header().map_err(std::io::Error::other)?;
    wr.write_image_data(px).map_err(std::io::Error::other)?;
    wr.finish().map_err(std::io::Error::other)
}
