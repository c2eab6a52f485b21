//! `ipfn bench`: speed on this machine beside floors measured in the same run.

use clap::Args;

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::input_error;

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
    if args.sizes.contains(&0) || args.volumes.contains(&0) {
        return Err(input_error!("--sizes/--volumes: sizes must be at least 1"));
    }
    if args.batches.contains(&0) {
        return Err(input_error!("--batches: batch sizes must be at least 1"));
    }
    if args.runs == 0 {
        return Err(input_error!("--runs 0: need at least one run"));
    }
    let devices = match &args.devices {
        Some(names) => names
            .iter()
            .map(|n| {
                let d: DeviceChoice = n.parse()?;
                d.burn_device()?; // fail now, with the device's own message
                Ok(d)
            })
            .collect::<Result<Vec<_>>>()?,
        None => {
            let mut found = vec![DeviceChoice::Cpu, DeviceChoice::Flex];
            for gpu in [DeviceChoice::Wgpu, DeviceChoice::Cuda] {
                match gpu.burn_device() {
                    Ok(_) if gpu == DeviceChoice::Wgpu && crate::device::wgpu_is_software() => {
                        eprintln!(
                            "wgpu: software adapter only (no GPU); skipped, name it in --devices to time it"
                        )
                    }
                    Ok(_) => found.push(gpu),
                    Err(e) => eprintln!("{}: skipped ({e})", bench::device_name(gpu)),
                }
            }
            found
        }
    };
    let plan = bench::BenchPlan {
        sizes: args.sizes.clone(),
        devices,
        runs: args.runs,
        train: !args.no_train,
        batches: args.batches.clone(),
        volumes: args.volumes.clone(),
    };
    println!(
        "ipfn {} bench on {}",
        env!("CARGO_PKG_VERSION"),
        bench::machine()
    );
    println!(
        "shipped honeycomb generator (10x128 MLP); medians of {} runs after a warm-up",
        args.runs
    );
    println!();
    println!("| work | device | ours | floor measured now (or reference) | ours / floor |");
    println!("|---|---|---|---|---|");
    bench::run(&plan, |row| println!("{}", row.markdown()))?;
    Ok(())
}
