//! `ipfn bench`: speed on this machine beside floors measured in the same run.

use clap::Args;

use crate::error::Result;

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Square sizes to synthesize, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "256,512,1024")]
    pub sizes: Vec<usize>,
    /// Devices, comma-separated: cpu, flex, wgpu, cuda. Default: cpu and flex, plus wgpu and
    /// cuda where they start (wgpu on a software adapter such as lavapipe is slow: name it).
    #[arg(long, value_delimiter = ',')]
    pub devices: Option<Vec<String>>,
    /// Timed runs per figure (the median is printed), after one warm-up run.
    #[arg(long, default_value_t = 3)]
    pub runs: usize,
    /// Skip the training iteration.
    #[arg(long)]
    pub no_train: bool,
    /// Batch sizes of the timed training iterations, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "4")]
    pub batches: Vec<usize>,
    /// Also paint cubes of these sides, comma-separated, with a 3D generator of the paper's size
    /// (10x128, random weights), e.g. --volumes 128,512.
    #[arg(long, value_delimiter = ',')]
    pub volumes: Vec<usize>,
}

pub(super) fn bench(args: BenchArgs) -> Result<()> {
    use crate::bench;
    let request = bench::BenchRequest {
        sizes: args.sizes,
        devices: args.devices,
        runs: args.runs,
        train: !args.no_train,
        batches: args.batches,
        volumes: args.volumes,
    };
    let (plan, skipped) = request.plan()?;
    for line in skipped {
        eprintln!("{line}");
    }
    println!(
        "ipfn {} bench on {}",
        env!("CARGO_PKG_VERSION"),
        bench::machine()
    );
    println!(
        "shipped honeycomb generator (10x128 MLP); medians of {} runs after a warm-up",
        plan.runs
    );
    println!();
    println!("| work | device | ours | floor measured now (or reference) | ours / floor |");
    println!("|---|---|---|---|---|");
    bench::run(&plan, |row| println!("{}", row.markdown()))?;
    Ok(())
}
