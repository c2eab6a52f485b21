//! The guide's "`ipfn view`: see the plane, follow training"
//! (docs/guide/view.md), as library calls.
//!
//! `cargo run --release --example 10_view` paints one tile of the viewer's plane (the shipped
//! honeycomb at zoom 1.5, seed 3, offset 256,-512) into `10_view.png` and prints the `ipfn synth`
//! command that paints the same pixels; with `--serve`, it then serves the viewer on a free
//! loopback port until Ctrl-C, as `ipfn view` does.

use std::path::Path;

use ipfn::device::DeviceChoice;
use ipfn::view::server::{ServerConfig, ViewServer};
use ipfn::view::{ModelSource, View, ViewModel, command_line, parse_query};

fn main() -> ipfn::Result<()> {
    let model = ViewModel::load(None, DeviceChoice::Cpu)?; // the shipped honeycomb
    // The view as the page's URL gives it to /tile.
    let view = View::from_query(&parse_query("seed=3&zoom=1.5&noise=1")?, &model)?;
    let png = model.tile_png(&view, [256, -512], [256, 256])?;
    let out = Path::new("10_view.png");
    std::fs::write(out, png).expect("writes 10_view.png");
    let args = view.synth_args(&model, [256, -512], [256, 256], Path::new("same.png"));
    println!(
        "wrote {}; the same pixels: {}",
        out.display(),
        command_line(&args)
    );

    if std::env::args().any(|a| a == "--serve") {
        ipfn::stop::install(ipfn::stop::OnSignal::ExitNow);
        let exporter = Box::new(|_: &[String]| {
            Err(ipfn::Error::Runtime("this example does not export".into()))
        });
        let source = ModelSource::new(None, DeviceChoice::Cpu);
        let server = ViewServer::bind(
            "127.0.0.1:0".parse().expect("an address"),
            source,
            None,
            ServerConfig::default(),
            exporter,
        )?;
        println!("http://{}/", server.addr());
        server.serve(ipfn::stop::flag())?;
    }
    Ok(())
}
