//! The guide's "`ipfn synth`: paint a sample", its seamless tiles
//! (docs/guide/synth.md), as library calls.
//!
//! `cargo run --release --example 03_tile` paints a 256x256 `--tile` of the shipped honeycomb,
//! lays it 2x2 and scores the seams (`ipfn eval`'s seam score: about 1 is seamless), then
//! paints the mirror tile of the same size. Writes `03_tile.png` and `03_mirror.png`.

use std::path::Path;

use ipfn::metrics::seam_score;
use ipfn::model::shipped_model;
use ipfn::synth::Synth;

fn main() -> ipfn::Result<()> {
    let (config, weights) = shipped_model()?;
    let (h, w) = (256, 256);
    // `ipfn synth --size 256 --tile --seed 3`: K and the latent lattice snap to the tile.
    let tile = Synth::new(config.clone(), weights.clone())
        .seed(3)
        .tile(&[h, w])
        .painter()?;
    if let Some(adjustment) = tile.tile_adjustment() {
        println!("{}", adjustment.describe());
    }
    let pixels = tile.render(&[0, 0], &[h, w]);
    // The plane repeats the tile exactly: the pixels one period away are the same.
    assert_eq!(tile.render(&[h as i64, w as i64], &[h, w]), pixels);
    let seams = seam_score(&pixels, h, w, config.channels)?;
    println!(
        "seam score laid 2x2: {:.3} (about 1 is seamless)",
        seams.overall
    );
    ipfn::io::write_png(Path::new("03_tile.png"), w, h, config.channels, &pixels)?;

    // `ipfn synth --size 256 --mirror`: a symmetric tile that repeats by plain copying.
    let mirror = Synth::new(config, weights)
        .seed(3)
        .mirror([h, w])
        .painter()?;
    let pixels = mirror.render(&[0, 0], &[h, w]);
    ipfn::io::write_png(Path::new("03_mirror.png"), w, h, 3, &pixels)?;
    println!("wrote 03_tile.png and 03_mirror.png");
    Ok(())
}
