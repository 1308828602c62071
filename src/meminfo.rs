//! What the kernel says about memory (Linux `/proc`; `None` elsewhere): the compliance checks a region fits before
//! allocating it, and the benchmarks and probes report their peak.

/// Memory a new allocation can take without swapping (`MemAvailable`), bytes.
pub fn available_bytes() -> Option<u64> {
    proc_field("/proc/meminfo", "MemAvailable:")
}

/// This process's peak resident memory so far (`VmHWM`), bytes.
pub fn peak_resident_bytes() -> Option<u64> {
    proc_field("/proc/self/status", "VmHWM:")
}

/// The value of a `Name:   1234 kB` line, in bytes.
fn proc_field(path: &str, name: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(name))?;
    line.split_whitespace().nth(1)?.parse::<u64>().ok().map(|kb| kb * 1024)
}

#[cfg(test)]
mod tests {
    #[test]
    fn linux_reports_both() {
        if cfg!(target_os = "linux") {
            assert!(super::available_bytes().is_some_and(|b| b > 0));
            assert!(super::peak_resident_bytes().is_some_and(|b| b > 0));
        }
    }
}
