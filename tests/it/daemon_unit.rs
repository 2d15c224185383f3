//! The systemd unit and `check-config`.

use std::path::Path;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_morphoid");

#[test]
fn the_systemd_unit_verifies_cleanly() {
    let Ok(version) = Command::new("systemd-analyze").arg("--version").output() else {
        eprintln!("skipped: systemd-analyze not found (Debian package: systemd)");
        return;
    };
    assert!(version.status.success());
    let unit = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("systemd/morphoid.service"),
    )
    .unwrap();
    for key in [
        "Type=notify",
        "WatchdogSec=",
        "User=morphoid",
        "SupplementaryGroups=dialout",
        "ProtectSystem=strict",
        "NoNewPrivileges=yes",
        "ExecReload=",
        // The console on loopback, nothing else on the network.
        "IPAddressDeny=any",
        "IPAddressAllow=localhost",
        // The light console's threads back at the daemon's priority.
        "LimitNICE=+0",
    ] {
        assert!(unit.contains(key), "{key} missing");
    }
    // verify checks that ExecStart exists: point it at this build.
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("morphoid.service");
    std::fs::write(&copy, unit.replace("/usr/local/bin/morphoid", BIN)).unwrap();
    let out = Command::new("systemd-analyze")
        .arg("verify")
        .arg(&copy)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    // Unknown or misspelt keys are only warnings: none allowed.
    assert!(text.trim().is_empty(), "{text}");
}

#[test]
fn the_packaged_configuration_serves_the_console_on_loopback() {
    let packaged = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("packaging/morphoid.toml"),
    )
    .unwrap();
    let (ok, text) = check(&packaged, &["--print"]);
    assert!(ok && text.starts_with("ok\n"), "{text}");
    assert!(text.contains("listen = \"127.0.0.1:8472\""), "{text}");
}

fn check(config: &str, extra: &[&str]) -> (bool, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.toml");
    std::fs::write(&path, config).unwrap();
    let out = Command::new(BIN)
        .arg("check-config")
        .arg("--config")
        .arg(&path)
        .args(extra)
        .output()
        .unwrap();
    (
        out.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

#[test]
fn check_config_accepts_the_example_and_names_wrong_keys_and_values() {
    let example =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/morphoid.toml"))
            .unwrap();
    let (ok, text) = check(&example, &["--print"]);
    assert!(ok && text.starts_with("ok\n"), "{text}");
    assert!(text.contains("settle_seconds = 2"), "{text}");

    let (ok, text) = check("[watch]\nsettle_secs = 2\n", &[]);
    assert!(!ok && text.contains("settle_secs"), "{text}");
    let (ok, text) = check("[watch]\nsettle_seconds = -3\n", &[]);
    assert!(!ok && text.contains("settle_seconds"), "{text}");
    let (ok, text) = check("[cp]\nwarp_width = 0\n", &[]);
    assert!(
        !ok && text.contains("[cp] warp_width = 0: must be"),
        "{text}"
    );
    let (ok, text) = check("[cp]\ndescent_steps = 0\n", &["--print"]);
    assert!(ok && text.contains("descent_steps = 0"), "{text}");
    let (ok, text) = check(
        "[serial]\nport = \"/dev/ttyUSB0\"\nbaud = 9600\ntrigger = \"^SCAN (\"\n",
        &[],
    );
    assert!(!ok && text.contains("serial.trigger"), "{text}");
    let (ok, text) = check(
        "[serial]\nport = \"/dev/ttyUSB0\"\nbaud = 12345\ntrigger = \"x\"\n",
        &[],
    );
    assert!(!ok && text.contains("12345"), "{text}");
    let (ok, text) = check(
        "[serial]\nport = \"/dev/ttyUSB0\"\nbaud = 9600\ntrigger = \"^SCAN\"\n",
        &[],
    );
    assert!(ok && text.contains("/dev/ttyUSB0 at 9600 baud"), "{text}");
}
