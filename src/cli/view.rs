//! `ipfn view`: serve the viewer page for a model or a run folder on a local port.

use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};

use clap::{Args, Parser};

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::input_error;
use crate::view::ModelSource;
use crate::view::server::{ServerConfig, ViewServer};

#[derive(Debug, Args)]
pub struct ViewArgs {
    /// A model file (.ipfn) or a training run folder (followed live: its plots, previews and
    /// newest checkpoint). Default: the most recent model in the working folder (a run's, if it
    /// is one), else the shipped honeycomb.
    pub path: Option<PathBuf>,
    /// Port to listen on; 0 picks a free one.
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Address to listen on. The default, 127.0.0.1, is reachable from this machine only;
    /// another address shows the page (and this machine's CPU) to others on the network.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: IpAddr,
    /// Where tiles are painted: cpu, flex, wgpu or cuda, as for synth.
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Memory for painted tiles, in MiB (least recently used tiles go first).
    #[arg(long, default_value_t = 256, value_name = "MIB")]
    pub cache_mb: usize,
    /// Folder that the page's export writes into. Default: the working folder.
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub export_dir: PathBuf,
}

/// The model file to paint and the run folder to follow.
fn resolve(path: Option<&Path>) -> Result<(Option<PathBuf>, Option<PathBuf>)> {
    let is_run =
        |dir: &Path| dir.join("metrics.csv").is_file() || dir.join("latest.ipfn").is_file();
    match path {
        Some(dir) if dir.is_dir() => {
            if !is_run(dir) {
                return Err(crate::file_error!(
                    &dir,
                    "not a training run folder (no metrics.csv or latest.ipfn); give a run folder or a model file",
                ));
            }
            Ok((Some(dir.join("latest.ipfn")), Some(dir.to_path_buf())))
        }
        Some(file) if file.is_file() => Ok((Some(file.to_path_buf()), None)),
        Some(missing) => Err(crate::file_error!(&missing, "no such file or folder",)),
        None => Ok(match crate::model::most_recent_model(Path::new(".")) {
            Some(model) => {
                let dir = model
                    .parent()
                    .filter(|d| is_run(d) && !d.as_os_str().is_empty());
                match dir {
                    Some(dir) => (Some(dir.join("latest.ipfn")), Some(dir.to_path_buf())),
                    None => (Some(model), None),
                }
            }
            None => (None, None),
        }),
    }
}

pub(super) fn view(args: ViewArgs) -> Result<()> {
    let device = DeviceChoice::resolve(&args.device)?;
    device.burn_device()?;
    let config = ServerConfig::new(args.cache_mb, args.export_dir.clone())?;
    let (model, run) = resolve(args.path.as_deref())?;
    let source = ModelSource::new(model.clone(), device);
    if run.is_none() {
        source.current()?; // a bad model file fails here, with its one-line error
    }
    let addr = SocketAddr::new(args.host, args.port);
    let server = ViewServer::bind(addr, source, run.clone(), config, Box::new(export))?;
    if !args.host.is_loopback() {
        eprintln!(
            "warning: listening on {}: anyone who can reach this address can use the viewer (and this machine's CPU)",
            args.host
        );
    }
    let what = match (&run, &model) {
        (Some(dir), _) => format!("run {} (following its latest.ipfn)", dir.display()),
        (None, Some(file)) => format!("model {}", file.display()),
        (None, None) => "the shipped honeycomb model".to_string(),
    };
    eprintln!("ipfn view: {what}");
    println!("{}", url(server.addr()));
    eprintln!("open that address in a browser; Ctrl-C stops the server");
    server.serve(crate::stop::flag())
}

/// Exports run `ipfn synth` itself, so the page's command and its file cannot differ.
fn export(synth_args: &[String]) -> Result<()> {
    let argv = ["ipfn", "synth"]
        .into_iter()
        .map(String::from)
        .chain(synth_args.iter().cloned());
    let cli = super::Cli::try_parse_from(argv)
        .map_err(|e| input_error!("export: {}", e.to_string().lines().next().unwrap_or("")))?;
    match cli.command {
        super::Command::Synth(a) => super::synth::synth(*a),
        _ => unreachable!("parsed as synth"),
    }
}

/// The address to open: a wildcard address is opened on loopback.
fn url(addr: SocketAddr) -> String {
    let host = match addr.ip() {
        ip if ip.is_unspecified() && addr.is_ipv6() => "[::1]".to_string(),
        ip if ip.is_unspecified() => "127.0.0.1".to_string(),
        ip if addr.is_ipv6() => format!("[{ip}]"),
        ip => ip.to_string(),
    };
    format!("http://{host}:{}/", addr.port())
}
