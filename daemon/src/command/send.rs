//! `interpd send PROGRAM`: streams a program through the library's client
//! ([`interpd::client::send`]) and exits non-zero unless its program reached
//! `done`.

use anyhow::{Result, bail};
use interpd::client::conn::connect;
use interpd::client::send::{Outcome, SendOptions, program_lines, stream};

/// Runs `send`.
pub fn run(args: &SendOptions) -> Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let load = |start: [f64; 6], server: &interpd::service::control::StatusReply| {
        program_lines(&args.program, start, server)
    };
    let (code, status) =
        rt.block_on(async { stream(connect(&args.endpoint()).await?, &load, args).await })?;
    if args.json {
        println!("{status}");
    } else {
        println!("final status: {status}");
    }
    match code {
        Outcome::Done => Ok(()),
        Outcome::Refused(e) => bail!("the server refused the program: {e}"),
        Outcome::Interrupted => bail!("interrupted: held and aborted"),
        Outcome::Ended { program, phase } => bail!(
            "program {program} did not reach done: it was {}",
            interpd::service::control::phase_name(phase)
        ),
        Outcome::Overtaken { program, now } => {
            bail!("program {program} was left behind: program {now} began before it was seen done")
        }
    }
}
