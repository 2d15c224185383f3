//! `[http]` in the configuration: its defaults, and each wrong value
//! refused naming its key.

use morphoid_service::config::{Config, Http};
use std::path::Path;

#[test]
fn http_settings_are_checked_and_named() {
    let p = Path::new("lab.toml");
    let off = Config::parse("", p).unwrap();
    assert_eq!(off.http, Http::default());
    assert_eq!(off.http.listen_addr().unwrap(), None);
    let on = Config::parse("[http]\nlisten = \"[::1]:8472\"\npublic_read = true\n", p).unwrap();
    assert_eq!(
        on.http.listen_addr().unwrap(),
        Some("[::1]:8472".parse().unwrap())
    );
    assert!(on.http.public_read);
    for (text, named) in [
        ("listen = \"localhost:8472\"", "http.listen"),
        ("listen = \"127.0.0.1\"", "http.listen"),
        ("max_header_bytes = 100", "http.max_header_bytes"),
        ("header_timeout_seconds = 0", "http.header_timeout_seconds"),
        (
            "request_timeout_seconds = -1",
            "http.request_timeout_seconds",
        ),
        ("session_hours = nan", "http.session_hours"),
        ("max_body_bytes = 0", "http.max_body_bytes"),
        (
            "login_failures_per_minute = 0",
            "http.login_failures_per_minute",
        ),
        ("tls_cert = \"c.pem\"", "http.tls_cert"),
        ("port = 8472", "port"),
    ] {
        let e = Config::parse(&format!("[http]\n{text}\n"), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains(named) && e.contains("lab.toml"), "{text}: {e}");
    }
}
