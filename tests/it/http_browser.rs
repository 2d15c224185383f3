//! The console in headless Chromium (Debian's `chromium`, installed by
//! `.ci/run`), driven over the DevTools protocol on a pipe: a curator logs
//! in through the form, confirms a scan on its page, and the overview shows
//! a new scan without reloading; no script error and no blocked script
//! (the pages' Content-Security-Policy) on the way. Skips without Chromium
//! unless `MORPHOID_REQUIRE_BROWSER=1`.

use crate::support::browser::chromium_or_skip;
use crate::support::http::{identified, settings, Console, PASSWORD};
use morphoid_service::store::Store;
use serde_json::{json, Value};
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::os::fd::{FromRawFd, RawFd};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// A pipe whose ends close on exec: (read end, write end).
fn pipe() -> (RawFd, RawFd) {
    let mut fds = [0; 2];
    // SAFETY: pipe2 writes two descriptors into the array it is given.
    let r = unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) };
    assert_eq!(r, 0, "pipe2");
    (fds[0], fds[1])
}

/// Headless Chromium speaking the DevTools protocol on fds 3 (commands)
/// and 4 (answers and events), killed when dropped.
struct Browser {
    child: Child,
    commands: File,
    answers: Receiver<Value>,
    events: Vec<Value>,
    next_id: u64,
    #[allow(dead_code)]
    profile: tempfile::TempDir,
}

impl Browser {
    fn start(binary: &PathBuf) -> Browser {
        let profile = tempfile::tempdir().unwrap();
        let (cmd_read, cmd_write) = pipe();
        let (ans_read, ans_write) = pipe();
        let mut command = Command::new(binary);
        command
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--remote-debugging-pipe",
                "--no-first-run",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        // SAFETY: only async-signal-safe calls (fcntl, dup2) between fork
        // and exec. The ends are first moved above 10 so that placing one
        // at 3 never overwrites the other.
        unsafe {
            command.pre_exec(move || {
                let high_cmd = libc::fcntl(cmd_read, libc::F_DUPFD, 10);
                let high_ans = libc::fcntl(ans_write, libc::F_DUPFD, 10);
                if high_cmd < 0
                    || high_ans < 0
                    || libc::dup2(high_cmd, 3) < 0
                    || libc::dup2(high_ans, 4) < 0
                {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = command.spawn().expect("start chromium");
        // SAFETY: each descriptor is ours alone from here on.
        let (commands, answers_file) = unsafe {
            libc::close(cmd_read);
            libc::close(ans_write);
            (File::from_raw_fd(cmd_write), File::from_raw_fd(ans_read))
        };
        let (tx, answers) = channel();
        std::thread::spawn(move || {
            let mut reader = BufReader::new(answers_file);
            loop {
                let mut message = Vec::new();
                match reader.read_until(0, &mut message) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {
                        message.pop();
                        if let Ok(v) = serde_json::from_slice::<Value>(&message) {
                            if tx.send(v).is_err() {
                                break;
                            }
                        }
                    }
                }
            }
        });
        Browser {
            child,
            commands,
            answers,
            events: Vec::new(),
            next_id: 0,
            profile,
        }
    }

    /// Send a command (to a page's `session`, or the browser) and wait for
    /// its answer, which must not be an error.
    fn call(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        let answer = self.send(session, method, params);
        assert!(answer.get("error").is_none(), "{method}: {answer}");
        answer["result"].clone()
    }

    /// Send a command and wait for its whole answer (a result or an
    /// error); events meanwhile are kept.
    fn send(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut message = json!({"id": id, "method": method, "params": params});
        if let Some(s) = session {
            message["sessionId"] = json!(s);
        }
        let mut bytes = serde_json::to_vec(&message).unwrap();
        bytes.push(0);
        self.commands.write_all(&bytes).expect("write to chromium");
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.answers.recv_timeout(left) {
                Ok(v) if v["id"] == id => return v,
                Ok(v) => self.events.push(v),
                Err(RecvTimeoutError::Timeout) => panic!("{method}: no answer"),
                Err(RecvTimeoutError::Disconnected) => panic!("{method}: chromium is gone"),
            }
        }
    }

    /// The value of `expression` in the page (null while the page is being
    /// replaced).
    fn eval(&mut self, session: &str, expression: &str) -> Value {
        let r = self.send(
            Some(session),
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true}),
        );
        r["result"]["result"]["value"].clone()
    }

    /// Wait until `expression` is true in the page (at most `limit`).
    fn until(&mut self, session: &str, expression: &str, limit: Duration) -> bool {
        let end = Instant::now() + limit;
        while Instant::now() < end {
            if self.eval(session, expression) == json!(true) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        false
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn http_a_curator_confirms_in_chromium_and_the_overview_follows() {
    let Some(binary) = chromium_or_skip() else {
        return;
    };
    let c = Console::start(&settings(false));
    c.add_curator("ana");
    let scan = c.ids.ateles_1;
    let mut b = Browser::start(&binary);
    let target = b.call(None, "Target.createTarget", json!({"url": "about:blank"}));
    let attached = b.call(
        None,
        "Target.attachToTarget",
        json!({"targetId": target["targetId"], "flatten": true}),
    );
    let s = attached["sessionId"].as_str().unwrap().to_string();
    b.call(Some(&s), "Runtime.enable", json!({}));
    b.call(Some(&s), "Log.enable", json!({}));
    let go = |b: &mut Browser, path: &str| {
        b.call(Some(&s), "Page.navigate", json!({"url": c.url(path)}));
    };
    let loaded = "document.readyState === 'complete'";
    let second = Duration::from_secs(1);

    // Reading needs a login: the overview sends the browser to the form.
    go(&mut b, "/");
    assert!(b.until(
        &s,
        &format!("{loaded} && location.pathname === '/login'"),
        10 * second
    ));
    b.eval(
        &s,
        &format!(
            "document.querySelector('input[name=name]').value = 'ana';\
             document.querySelector('input[name=password]').value = '{PASSWORD}';\
             document.getElementById('login').submit(); true"
        ),
    );
    assert!(
        b.until(
            &s,
            &format!("{loaded} && location.pathname === '/' && !!document.getElementById('user')"),
            15 * second
        ),
        "not logged in: {}",
        b.eval(&s, "document.body.innerText")
    );

    // Confirm the scan on its page.
    go(&mut b, &format!("/scans/{scan}"));
    assert!(b.until(
        &s,
        &format!("{loaded} && !!document.getElementById('review-form')"),
        10 * second
    ));
    b.eval(
        &s,
        "document.querySelector('input[value=confirm]').checked = true;\
         document.getElementById('review-form').submit(); true",
    );
    assert!(
        b.until(
            &s,
            &format!("{loaded} && !!document.querySelector('#reviews td.decision')"),
            15 * second
        ),
        "no decision shown: {}",
        b.eval(&s, "document.body.innerText")
    );
    assert_eq!(
        b.eval(
            &s,
            "document.querySelector('#reviews td.decision').innerText"
        ),
        json!("confirm")
    );
    let reviews = Store::open(&c.db).unwrap().reviews_of(scan).unwrap();
    assert_eq!(reviews.len(), 1);
    assert_eq!(
        (reviews[0].curator.as_str(), reviews[0].decision.as_str()),
        ("ana", "confirm")
    );

    // The overview: a scan identified now appears without a reload.
    go(&mut b, "/");
    assert!(b.until(
        &s,
        &format!("{loaded} && !!document.getElementById('scans')"),
        10 * second
    ));
    assert!(b.until(
        &s,
        "document.getElementById('live').innerText.includes('up to date')",
        10 * second
    ));
    b.eval(&s, "window.notReloaded = true; true");
    assert_eq!(
        b.eval(
            &s,
            "document.getElementById('scans').innerText.includes('live-new.ply')"
        ),
        json!(false)
    );
    identified(
        &mut Store::open(&c.db).unwrap(),
        "export/live-new.ply",
        42,
        "Cebus",
        "Cebidae",
        false,
    );
    assert!(
        b.until(
            &s,
            "document.getElementById('scans').innerText.includes('live-new.ply')",
            15 * second
        ),
        "the new scan did not appear: {}",
        b.eval(&s, "document.getElementById('scans').innerText")
    );
    assert_eq!(
        b.eval(&s, "window.notReloaded === true"),
        json!(true),
        "the page was reloaded"
    );

    // No script error, nothing blocked by the policy.
    let problems: Vec<&Value> = b
        .events
        .iter()
        .filter(|e| match e["method"].as_str() {
            Some("Runtime.exceptionThrown") => true,
            Some("Log.entryAdded") => {
                let entry = &e["params"]["entry"];
                entry["level"] == "error" && entry["source"] != "network"
            }
            _ => false,
        })
        .collect();
    assert!(problems.is_empty(), "{problems:#?}");
}
