//! What a report says about where its figures come from: the commit, the CPU and the date.

/// The checkout's commit (`git describe --always`, with `-dirty` when tracked files other than
/// `outputs` differ from it), so that a reader can tell which code the figures are from; a report's
/// own earlier output does not make its checkout dirty.
pub fn commit(outputs: &[&std::path::Path]) -> String {
    let Some(described) = command_output("git", &["describe", "--always"]) else {
        return "an unknown commit".into();
    };
    let mut args = vec![
        "diff".to_string(),
        "--quiet".into(),
        "HEAD".into(),
        "--".into(),
        ".".into(),
    ];
    args.extend(outputs.iter().map(|p| format!(":(exclude){}", p.display())));
    let clean = std::process::Command::new("git")
        .args(&args)
        .status()
        .is_ok_and(|s| s.success());
    if clean {
        described
    } else {
        format!("{described}-dirty")
    }
}

/// Today's date in UTC (`date -u +%F`).
pub fn date() -> String {
    command_output("date", &["-u", "+%F"]).unwrap_or_else(|| "an unknown date".into())
}

/// The compiler that built this binary's crate, as `rustc --version` prints it.
pub fn rustc() -> String {
    command_output("rustc", &["--version"]).unwrap_or_else(|| "an unknown rustc".into())
}

/// The CPU's name, family and model as Linux reports them: the timings are this machine's.
pub fn cpu() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |key: &str| {
        info.lines()
            .filter_map(|l| l.split_once(':'))
            .find(|(k, _)| k.trim() == key)
            .map(|(_, v)| v.trim().to_string())
    };
    match (field("model name"), field("cpu family"), field("model")) {
        (Some(name), Some(family), Some(model)) => {
            format!("{name} (family {family}, model {model})")
        }
        (Some(name), ..) => name,
        _ => "an unknown CPU".into(),
    }
}

/// The threads the machine offers this process.
pub fn threads() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
}

fn command_output(program: &str, args: &[&str]) -> Option<String> {
    std::process::Command::new(program)
        .args(args)
        .output()
        .ok()
        .filter(|out| out.status.success())
        .and_then(|out| String::from_utf8(out.stdout).ok())
        .map(|s| s.trim().to_string())
}
