//! The console over HTTPS (`[http] tls_cert`, `tls_key`): a real TLS
//! handshake with a client that trusts only the test's self-signed
//! certificate; cookies marked `Secure`; plain HTTP to the port gets no
//! answer; an unusable certificate stops the start, naming the file.

use crate::support::http::{library_folder, raw_get, settings, sources, Console};
use morphoid_service::http::{LiveStatus, Server};
use std::io::{Read, Write};
use std::sync::Arc;
use std::time::Duration;

/// A self-signed certificate for localhost and 127.0.0.1, written to
/// `dir`: (certificate PEM, its file, the key's file).
fn certificate(dir: &std::path::Path) -> (String, std::path::PathBuf, std::path::PathBuf) {
    let made =
        rcgen::generate_simple_self_signed(vec!["localhost".to_string(), "127.0.0.1".to_string()])
            .expect("certificate");
    let pem = made.cert.pem();
    let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
    std::fs::write(&cert, &pem).unwrap();
    std::fs::write(&key, made.signing_key.serialize_pem()).unwrap();
    (pem, cert, key)
}

/// GET `path` over TLS, trusting only `ca_pem`: the whole answer.
#[allow(deprecated)] // ring's provider, as the server uses
fn https_get(addr: std::net::SocketAddr, ca_pem: &str, path: &str) -> String {
    use rustls::pki_types::pem::PemObject as _;
    use rustls::pki_types::{CertificateDer, ServerName};
    let mut roots = rustls::RootCertStore::empty();
    roots
        .add(CertificateDer::from_pem_slice(ca_pem.as_bytes()).unwrap())
        .unwrap();
    let config = rustls::ClientConfig::builder_with_provider(Arc::new(
        rustls::crypto::ring::default_provider(),
    ))
    .with_safe_default_protocol_versions()
    .unwrap()
    .with_root_certificates(roots)
    .with_no_client_auth();
    let name = ServerName::try_from("localhost").unwrap();
    let connection = rustls::ClientConnection::new(Arc::new(config), name).unwrap();
    let tcp = std::net::TcpStream::connect(addr).unwrap();
    tcp.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut tls = rustls::StreamOwned::new(connection, tcp);
    // The handshake happens on the first write.
    tls.write_all(
        format!("GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n").as_bytes(),
    )
    .expect("handshake and request");
    let mut answer = Vec::new();
    let _ = tls.read_to_end(&mut answer);
    String::from_utf8_lossy(&answer).into_owned()
}

#[test]
fn http_the_console_serves_https_with_secure_cookies() {
    let dir = tempfile::tempdir().unwrap();
    let (pem, cert, key) = certificate(dir.path());
    let mut tls = settings(true);
    tls.tls_cert = Some(cert.clone());
    tls.tls_key = Some(key.clone());
    let c = Console::start(&tls);

    let health = https_get(c.addr(), &pem, "/healthz");
    assert!(health.starts_with("HTTP/1.1 200"), "{health}");
    assert!(health.contains("{\"status\":\"ok\"}"), "{health}");
    let scans = https_get(c.addr(), &pem, "/api/v1/scans?genus=Ateles");
    assert!(
        scans.contains("ateles-5.ply") && !scans.contains("alouatta"),
        "{scans}"
    );
    let login = https_get(c.addr(), &pem, "/login");
    let cookie = login
        .lines()
        .find(|l| {
            l.to_ascii_lowercase()
                .starts_with("set-cookie: morphoid_login_csrf=")
        })
        .expect("the login form's cookie");
    assert!(
        cookie.contains("; Secure") && cookie.contains("HttpOnly"),
        "{cookie}"
    );

    // Plain HTTP on the HTTPS port: no HTTP answer.
    let (status, _) = raw_get(c.addr(), "/healthz");
    assert_eq!(status, 0);

    // A certificate that is not one stops the start, naming the file.
    std::fs::write(&cert, "not a certificate").unwrap();
    let db = dir.path().join("db.sqlite");
    drop(morphoid_service::store::Store::open(&db).unwrap());
    let library = library_folder(dir.path());
    let e = Server::start(
        "127.0.0.1:0".parse().unwrap(),
        &tls,
        sources(&db, &library, &LiveStatus::new()),
    )
    .expect_err("a broken certificate");
    assert!(e.to_string().contains(&cert.display().to_string()), "{e}");
}
