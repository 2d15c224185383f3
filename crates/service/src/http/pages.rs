//! The console's pages, rendered on the server: the overview (the
//! reports' `index_html`, with a filter form and rows that follow the
//! database live), each scan's report (the reports' `report_html`, from
//! the database, with the curators' decisions and the form to take one),
//! the library, the daemon's state, and logging in and out.
//!
//! Every page carries a Content-Security-Policy whose script nonce is new
//! per response: only the console's own scripts run, whatever a file name
//! or a taxon holds (all of which are escaped besides).

use super::api::{decision_of, record_decision, scan_id};
use super::auth::{
    cookie, identify, may_read, random_hex, same_secret, set_cookie, verify_password, writer,
    Identity, LOGIN_CSRF_COOKIE, SESSION_COOKIE,
};
use super::error::ApiError;
use super::query::scan_query;
use super::server::PeerAddr;
use super::state::AppState;
use crate::report::{index_html, report_html, utc_time, IndexRow, PageLink};
use crate::store::{ReviewRecord, ScanQuery, ScanRecord, DEFAULT_NEAREST};
use axum::extract::rejection::FormRejection;
use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode, Uri};
use axum::response::{Html, IntoResponse, Response};
use axum::{Extension, Form};
use morphoid_data::present::escape;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Arc;

/// The style of the console's own pages and of its navigation bar.
const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;\
text-align:left;vertical-align:top}th{background:#f3f3f3}.muted{color:#777}.bad{color:#c00}\
.ok{color:#070}";

/// The navigation bar's own style (also put into the reports' pages).
const NAV_STYLE: &str = "<style>#console-nav{background:#f3f3f3;padding:.4em .8em;\
margin:-.5em 0 1em 0;border-bottom:1px solid #ccc}#console-nav form{display:inline}\
#console-nav .who{float:right}#filters label{margin-right:.8em}\
#review-form fieldset{margin:.5em 0}</style>";

/// How often the live overview asks whether anything changed.
const POLL_MS: u32 = 2000;

/// The navigation bar: the pages, and who is logged in.
fn nav(identity: &Identity) -> String {
    let who = match (identity.user(), identity.csrf()) {
        (Some(user), Some(csrf)) => format!(
            "curator <b id=\"user\">{}</b> <form method=\"post\" action=\"/logout\">\
             <input type=\"hidden\" name=\"csrf\" value=\"{}\"><button>Log out</button></form>",
            escape(user),
            escape(csrf)
        ),
        (Some(user), None) => format!("curator <b id=\"user\">{}</b>", escape(user)),
        (None, _) => "<a href=\"/login\">Log in</a>".to_string(),
    };
    format!(
        "{NAV_STYLE}<nav id=\"console-nav\"><a href=\"/\">Overview</a> · \
         <a href=\"/library\">Library</a> · <a href=\"/status\">Daemon</a> · \
         <a href=\"/api/v1/openapi.json\">API</a><span class=\"who\">{who}</span></nav>\n"
    )
}

/// A whole page of the console's own.
fn page(title: &str, identity: &Identity, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>morphoid: {t}</title><style>{STYLE}</style></head><body>\n{}<h1>{t}</h1>\n\
         {body}</body></html>\n",
        nav(identity),
        t = escape(title)
    )
}

/// `html` (a report's page) with `top` just inside `<body>` and `bottom`
/// just before `</body>`.
fn inject(html: &str, top: &str, bottom: &str) -> String {
    let mut out = String::with_capacity(html.len() + top.len() + bottom.len());
    match html.split_once("<body>") {
        Some((head, rest)) => {
            out.push_str(head);
            out.push_str("<body>\n");
            out.push_str(top);
            out.push_str(rest);
        }
        None => out.push_str(html),
    }
    match out.rfind("</body>") {
        Some(at) => out.insert_str(at, bottom),
        None => out.push_str(bottom),
    }
    out
}

/// A page as a response: its scripts get this response's nonce, which the
/// Content-Security-Policy names; never cached.
fn html_response(status: StatusCode, html: String) -> Response {
    let nonce = random_hex(16);
    let html = html.replace("<script>", &format!("<script nonce=\"{nonce}\">"));
    let mut response = (status, Html(html)).into_response();
    let csp = format!(
        "default-src 'none'; script-src 'nonce-{nonce}'; style-src 'unsafe-inline'; \
         img-src 'self' data:; connect-src 'self'; form-action 'self'; \
         frame-ancestors 'none'; base-uri 'none'"
    );
    let headers = response.headers_mut();
    if let Ok(v) = HeaderValue::from_str(&csp) {
        headers.insert(header::CONTENT_SECURITY_POLICY, v);
    }
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    response
}

/// 303 See Other to `location` (a path of the console's own).
fn see_other(location: &str) -> Response {
    let mut response = StatusCode::SEE_OTHER.into_response();
    let value = HeaderValue::from_str(location).unwrap_or(HeaderValue::from_static("/"));
    response.headers_mut().insert(header::LOCATION, value);
    response
}

/// A `next` address to go back to after logging in: a path of this site
/// only (never another host, `//host` or `\`).
fn safe_next(next: Option<&str>) -> String {
    match next {
        Some(n)
            if n.starts_with('/')
                && !n.starts_with("//")
                && !n.contains('\\')
                && n.len() <= 2000
                && n.bytes().all(|b| b.is_ascii_graphic()) =>
        {
            n.to_string()
        }
        _ => "/".to_string(),
    }
}

/// Who may read this page, or the response that sends them to log in.
async fn reader(
    state: &Arc<AppState>,
    headers: &HeaderMap,
    uri: &Uri,
) -> Result<Identity, Response> {
    let identity = identify(state, headers)
        .await
        .map_err(ApiError::into_page)?;
    match may_read(state, &identity) {
        Ok(()) => Ok(identity),
        Err(_) => {
            let here = uri.path_and_query().map_or("/", |p| p.as_str());
            let next = serde_urlencoded::to_string([("next", here)]).unwrap_or_default();
            Err(see_other(&format!("/login?{next}")))
        }
    }
}

/// The query's raw pairs (for the form's values and the paging links).
fn query_pairs(raw: Option<&str>) -> Vec<(String, String)> {
    serde_urlencoded::from_str(raw.unwrap_or("")).unwrap_or_default()
}

/// `GET /`: the overview, newest first, with the filter form; its rows
/// follow the database without a reload.
pub(super) async fn overview(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    uri: Uri,
    RawQuery(raw): RawQuery,
) -> Response {
    let identity = match reader(&state, &headers, &uri).await {
        Ok(i) => i,
        Err(r) => return r,
    };
    let query = match scan_query(raw.as_deref(), &state.ranks, &[]) {
        Ok(q) => q,
        Err(e) => return e.into_page(),
    };
    let pairs = query_pairs(raw.as_deref());
    let key = format!("overview?{}", raw.as_deref().unwrap_or(""));
    let rows = state
        .answers
        .answer(key, {
            let (state, pairs) = (Arc::clone(&state), pairs.clone());
            move || async move { overview_rows(&state, query, &pairs).await }
        })
        .await;
    let html = match rows {
        Ok(html) => html,
        Err(e) => return e.into_page(),
    };
    let top = format!("{}{}", nav(&identity), filter_form(&state, &pairs));
    html_response(StatusCode::OK, inject(&html, &top, &live_script()))
}

/// The overview's page without the navigation, filters and script: the
/// scans of `query`, each followed by its specimens, and the link to older
/// ones. The same for every reader, so it is kept until the database
/// changes.
async fn overview_rows(
    state: &AppState,
    query: ScanQuery,
    pairs: &[(String, String)],
) -> Result<String, ApiError> {
    let scan_page = state
        .pool
        .run(move |store| store.search_scans(&query))
        .await?;
    // A scan of several specimens: its specimens' rows follow it.
    let records: Vec<&ScanRecord> = scan_page
        .scans
        .iter()
        .flat_map(|r| std::iter::once(r).chain(&r.specimens))
        .collect();
    let links: Vec<String> = records.iter().map(|r| format!("/scans/{}", r.id)).collect();
    let rows: Vec<IndexRow<'_>> = records
        .iter()
        .zip(&links)
        .map(|(record, report)| IndexRow {
            record,
            report,
            thumbnail: None,
        })
        .collect();
    let mut pages = Vec::new();
    if let Some(cursor) = scan_page.next_cursor {
        let mut next: Vec<(String, String)> = pairs
            .iter()
            .filter(|(k, _)| k != "cursor" && k != "offset")
            .cloned()
            .collect();
        next.push(("cursor".into(), cursor.to_string()));
        pages.push(PageLink {
            href: format!(
                "/?{}",
                serde_urlencoded::to_string(&next).unwrap_or_default()
            ),
            label: format!("older scans (before scan {cursor})"),
        });
    }
    Ok(index_html("scans", &rows, &pages))
}

/// The filter form, filled with the query's values.
fn filter_form(state: &AppState, pairs: &[(String, String)]) -> String {
    let value = |key: &str| {
        pairs
            .iter()
            .rev()
            .find(|(k, _)| k == key)
            .map_or(String::new(), |(_, v)| escape(v))
    };
    let select = |key: &str, options: &[&str]| {
        let current = value(key);
        let mut s = format!("<select name=\"{key}\"><option value=\"\">any</option>");
        for o in options {
            let selected = if current == *o { " selected" } else { "" };
            let _ = write!(s, "<option{selected}>{o}</option>");
        }
        s.push_str("</select>");
        s
    };
    let mut ranks: Vec<&str> = state.ranks.iter().map(String::as_str).collect();
    if ranks.is_empty() {
        ranks.push("genus");
    }
    format!(
        "<form id=\"filters\" method=\"get\" action=\"/\">\
         <label>Status {}</label>\
         <label>Taxon {} <input name=\"taxon\" size=\"14\" value=\"{}\"></label>\
         <label>No close match {}</label><label>Reviewed {}</label>\
         <label>Queued from <input type=\"date\" name=\"since\" value=\"{}\"></label>\
         <label>to <input type=\"date\" name=\"until\" value=\"{}\"></label>\
         <label>File name <input name=\"name\" size=\"16\" value=\"{}\"></label>\
         <button>Filter</button> <a href=\"/\">clear</a></form>\n\
         <p id=\"live\" class=\"muted\">live: rows update as scans arrive</p>\n",
        select(
            "status",
            &[
                "pending",
                "running",
                "ok",
                "error",
                "duplicate",
                "superseded"
            ]
        ),
        select("rank", &ranks),
        value("taxon"),
        select("no_close_match", &["true", "false"]),
        select("reviewed", &["true", "false"]),
        value("since"),
        value("until"),
        value("name"),
    )
}

/// The overview's script: asks `/api/v1/changes` every [`POLL_MS`]; when
/// the answer changes, fetches the same page again and swaps its rows in,
/// and once more on the next poll, since the page may be up to 1 s (the
/// answer cache's bound, less than a poll) behind the change.
fn live_script() -> String {
    format!(
        "<script>\n(function(){{\n\
         var last=null,again=false,busy=false,live=document.getElementById('live');\n\
         function stamp(){{live.textContent='live: up to date at '+new Date().toLocaleTimeString();}}\n\
         function swap(){{return fetch(location.href,{{credentials:'same-origin',cache:'no-store'}})\
         .then(function(r){{return r.text();}}).then(function(t){{\
         var d=new DOMParser().parseFromString(t,'text/html');\
         ['scans','pages'].forEach(function(id){{var n=d.getElementById(id),o=document.getElementById(id);\
         if(n&&o){{o.replaceWith(n);}}else if(n){{document.body.appendChild(n);}}else if(o){{o.remove();}}}});}});}}\n\
         function tick(){{if(busy){{return;}}busy=true;\
         fetch('/api/v1/changes',{{credentials:'same-origin',cache:'no-store'}})\
         .then(function(r){{if(!r.ok){{throw new Error(r.status);}}return r.json();}})\
         .then(function(j){{var changed=last!==null&&j.changes!==last;last=j.changes;\
         var fetchNow=changed||again;again=changed;return fetchNow?swap():null;}})\
         .then(stamp,function(){{live.textContent='live: connection lost, retrying';}})\
         .then(function(){{busy=false;}});}}\n\
         tick();setInterval(tick,{POLL_MS});\n}})();\n</script>\n"
    )
}

/// `GET /scans/{id}`: the scan's report from the database, its decisions
/// and (for a logged-in curator) the form to take one.
pub(super) async fn scan_page(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    uri: Uri,
    Path(id): Path<String>,
) -> Response {
    let identity = match reader(&state, &headers, &uri).await {
        Ok(i) => i,
        Err(r) => return r,
    };
    let id = match scan_id(&id) {
        Ok(id) => id,
        Err(e) => return e.into_page(),
    };
    let read = state
        .pool
        .run(move |store| {
            let record = store
                .scan(id, DEFAULT_NEAREST)?
                .ok_or_else(|| ApiError::NotFound(format!("no scan with id {id}")))?;
            Ok::<_, ApiError>((record, store.reviews_of(id)?))
        })
        .await;
    let (record, reviews) = match read {
        Ok(r) => r,
        Err(e) => return e.into_page(),
    };
    // A scan that was not identified has nothing to draw.
    let mut html = if record.nearest.is_empty() {
        report_html(&record, None, None)
    } else {
        match state.pictures.scene(state.live.classifier(), &record).await {
            Ok(scene) => report_html(&record, Some(&scene), None),
            Err(why) => report_html(&record, None, Some(&why.to_string())),
        }
    };
    // The report links its specimens' pages by file name; here they are
    // found by id.
    for s in &record.specimens {
        let by_name =
            crate::report::href_of(&format!("{}.html", crate::report::file_name(&s.path)));
        html = html.replace(
            &format!("href=\"{}\"", escape(&by_name)),
            &format!("href=\"/scans/{}\"", s.id),
        );
    }
    let bottom = decisions(&state, &identity, &record, &reviews);
    html_response(StatusCode::OK, inject(&html, &nav(&identity), &bottom))
}

/// The decisions taken on a scan, and the form to take the next one.
fn decisions(
    state: &AppState,
    identity: &Identity,
    record: &ScanRecord,
    reviews: &[ReviewRecord],
) -> String {
    let mut h = String::from("<h2>Curators' decisions</h2>\n");
    let taxa_text = |taxa: &BTreeMap<String, String>| {
        taxa.iter()
            .map(|(r, t)| format!("{}: <b>{}</b>", escape(r), escape(t)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if reviews.is_empty() {
        h.push_str("<p id=\"reviews\" class=\"muted\">None yet.</p>\n");
    } else {
        h.push_str(
            "<table id=\"reviews\"><tr><th>#</th><th>When</th><th>Curator</th>\
             <th>Decision</th><th>Taxa</th><th>Comment</th></tr>\n",
        );
        for r in reviews {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"decision\">{}</td>\
                 <td>{}</td><td>{}</td></tr>",
                r.seq,
                utc_time(r.decided_at_ms),
                escape(&r.curator),
                escape(&r.decision),
                taxa_text(&r.taxa),
                escape(r.comment.as_deref().unwrap_or("")),
            );
        }
        h.push_str("</table>\n");
    }
    if record.specimen_count.is_some() {
        h.push_str("<p class=\"muted\">Each specimen is decided on, on its own page.</p>\n");
        return h;
    }
    let Some(csrf) = identity.csrf() else {
        let _ = writeln!(
            h,
            "<p><a href=\"/login?next=/scans/{}\">Log in</a> to confirm, correct or reject \
             this identification.</p>",
            record.id
        );
        return h;
    };
    let ranks: Vec<String> = if state.ranks.is_empty() {
        record.ranks.iter().map(|r| r.rank.clone()).collect()
    } else {
        state.ranks.clone()
    };
    let latest = reviews
        .last()
        .map_or("none".to_string(), |r| r.id.to_string());
    let _ = write!(
        h,
        "<form id=\"review-form\" method=\"post\" action=\"/scans/{}/review\">\
         <input type=\"hidden\" name=\"csrf\" value=\"{}\">\
         <input type=\"hidden\" name=\"expected_latest\" value=\"{latest}\"><fieldset>",
        record.id,
        escape(csrf),
    );
    if !record.ranks.is_empty() {
        h.push_str(
            "<label><input type=\"radio\" name=\"decision\" value=\"confirm\" checked> \
             Confirm</label><br>",
        );
    }
    h.push_str(
        "<label><input type=\"radio\" name=\"decision\" value=\"correct\"> Correct to:</label>",
    );
    for rank in &ranks {
        let current = record
            .ranks
            .iter()
            .find(|r| &r.rank == rank)
            .map_or("", |r| r.taxon.as_str());
        let _ = write!(
            h,
            " <label>{r} <input name=\"taxon.{r}\" size=\"14\" placeholder=\"{}\"></label>",
            escape(current),
            r = escape(rank)
        );
    }
    h.push_str(
        "<br><label><input type=\"radio\" name=\"decision\" value=\"reject\"> Reject \
         (unusable scan)</label><br><label>Comment <input name=\"comment\" size=\"50\" \
         maxlength=\"2000\"></label></fieldset><button>Record the decision</button></form>\n",
    );
    h
}

/// The value of `key` among form fields (the last one).
fn field<'a>(fields: &'a [(String, String)], key: &str) -> Option<&'a str> {
    fields
        .iter()
        .rev()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

/// A form body, or the page saying why it could not be read. A body that
/// is not a form counts as an empty one, so that who is asking (and their
/// CSRF token) is what is refused first; one over the size limit is
/// refused as such.
fn form_fields(
    form: Result<Form<Vec<(String, String)>>, FormRejection>,
) -> Result<Vec<(String, String)>, ApiError> {
    match form {
        Ok(Form(fields)) => Ok(fields),
        Err(e) if e.status() == StatusCode::PAYLOAD_TOO_LARGE => {
            Err(ApiError::TooLarge(e.body_text()))
        }
        Err(_) => Ok(Vec::new()),
    }
}

/// `POST /scans/{id}/review`: the decision form; back to the scan's page.
pub(super) async fn review_form(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    Path(id): Path<String>,
    form: Result<Form<Vec<(String, String)>>, FormRejection>,
) -> Response {
    let identity = match identify(&state, &headers).await {
        Ok(i) => i,
        Err(e) => return e.into_page(),
    };
    let fields = match form_fields(form) {
        Ok(f) => f,
        Err(e) => return e.into_page(),
    };
    let curator = match writer(&identity, field(&fields, "csrf")) {
        Ok(c) => c.to_string(),
        Err(e) => return e.into_page(),
    };
    let id = match scan_id(&id) {
        Ok(id) => id,
        Err(e) => return e.into_page(),
    };
    let name = field(&fields, "decision").unwrap_or("");
    let taxa: BTreeMap<String, String> = if name == "correct" {
        fields
            .iter()
            .filter_map(|(k, v)| {
                Some((k.strip_prefix("taxon.")?.to_string(), v.trim().to_string()))
            })
            .filter(|(_, v)| !v.is_empty())
            .collect()
    } else {
        BTreeMap::new()
    };
    let expected = match field(&fields, "expected_latest") {
        None => None,
        Some("none") => Some(None),
        Some(n) => match n.parse() {
            Ok(n) => Some(Some(n)),
            Err(_) => return ApiError::BadRequest(format!("expected_latest {n:?}")).into_page(),
        },
    };
    let comment = field(&fields, "comment").map(str::to_string);
    let recorded = match decision_of(name, taxa) {
        Ok(decision) => record_decision(&state, curator, id, decision, comment, expected).await,
        Err(e) => Err(e),
    };
    match recorded {
        Ok(_) => see_other(&format!("/scans/{id}")),
        Err(e) => e.into_page(),
    }
}

/// The login form (a CSRF token in a cookie and in the form).
fn login_page(identity: &Identity, next: &str, message: Option<&str>) -> (String, String) {
    let csrf = random_hex(32);
    let message = message
        .map(|m| format!("<p class=\"bad\" id=\"error\">{}</p>", escape(m)))
        .unwrap_or_default();
    let body = format!(
        "{message}<form id=\"login\" method=\"post\" action=\"/login\">\
         <input type=\"hidden\" name=\"csrf\" value=\"{csrf}\">\
         <input type=\"hidden\" name=\"next\" value=\"{}\">\
         <p><label>User <input name=\"name\" autocomplete=\"username\" required></label></p>\
         <p><label>Password <input type=\"password\" name=\"password\" \
         autocomplete=\"current-password\" required></label></p>\
         <button>Log in</button></form>\n",
        escape(next)
    );
    (page("log in", identity, &body), csrf)
}

/// The login page as a response, with its CSRF cookie.
fn login_response(
    state: &AppState,
    status: StatusCode,
    next: &str,
    message: Option<&str>,
) -> Response {
    let (html, csrf) = login_page(&Identity::Anonymous, next, message);
    let mut response = html_response(status, html);
    let cookie = set_cookie(
        LOGIN_CSRF_COOKIE,
        &csrf,
        "/login",
        3600,
        state.secure_cookies,
    );
    if let Ok(v) = HeaderValue::from_str(&cookie) {
        response.headers_mut().append(header::SET_COOKIE, v);
    }
    response
}

/// `GET /login`.
pub(super) async fn login_form(
    State(state): State<Arc<AppState>>,
    RawQuery(raw): RawQuery,
) -> Response {
    let pairs = query_pairs(raw.as_deref());
    let next = safe_next(field(&pairs, "next"));
    login_response(&state, StatusCode::OK, &next, None)
}

/// `POST /login`: name and password; failures are counted per client
/// address and per name, and refused past `[http]
/// login_failures_per_minute`.
pub(super) async fn login(
    State(state): State<Arc<AppState>>,
    Extension(PeerAddr(peer)): Extension<PeerAddr>,
    headers: HeaderMap,
    form: Result<Form<Vec<(String, String)>>, FormRejection>,
) -> Response {
    let fields = match form_fields(form) {
        Ok(f) => f,
        Err(e) => return e.into_page(),
    };
    let next = safe_next(field(&fields, "next"));
    let sent = field(&fields, "csrf").unwrap_or("");
    let expected = cookie(&headers, LOGIN_CSRF_COOKIE).unwrap_or_default();
    if expected.is_empty() || !same_secret(sent, &expected) {
        return ApiError::Forbidden("missing or wrong CSRF token (reload the login page)".into())
            .into_page();
    }
    let name = field(&fields, "name").unwrap_or("").trim().to_string();
    let password = field(&fields, "password").unwrap_or("").to_string();
    let keys = vec![format!("ip:{}", peer.ip()), format!("user:{name}")];
    if let Err(wait) = state.limiter.check(&keys) {
        tracing::warn!(
            "http: login of {name:?} from {} refused: too many failures",
            peer.ip()
        );
        return ApiError::TooManyRequests(wait).into_page();
    }
    let who = name.clone();
    let stored = match state
        .pool
        .run(move |store| store.curator_password_hash(&who))
        .await
    {
        Ok(h) => h,
        Err(e) => return e.into_page(),
    };
    let known = stored.is_some();
    let hash = stored.unwrap_or_else(|| state.dummy_hash.clone());
    let matches = {
        // One check at a time: argon2 is slow on purpose.
        let _permit = state.password_checks.acquire().await;
        tokio::task::spawn_blocking(move || verify_password(&password, &hash))
            .await
            .unwrap_or(false)
    };
    if !(known && matches) {
        state.limiter.failed(&keys);
        tracing::warn!("http: failed login as {name:?} from {}", peer.ip());
        return login_response(
            &state,
            StatusCode::UNAUTHORIZED,
            &next,
            Some("Wrong user name or password."),
        );
    }
    let (value, _) = state.sessions.create(&name);
    tracing::info!("http: {name} logged in from {}", peer.ip());
    let mut response = see_other(&next);
    let max_age = (state.settings.session_hours * 3600.0) as u64;
    for c in [
        set_cookie(SESSION_COOKIE, &value, "/", max_age, state.secure_cookies),
        set_cookie(LOGIN_CSRF_COOKIE, "", "/login", 0, state.secure_cookies),
    ] {
        if let Ok(v) = HeaderValue::from_str(&c) {
            response.headers_mut().append(header::SET_COOKIE, v);
        }
    }
    response
}

/// `POST /logout` (with the session's CSRF token).
pub(super) async fn logout(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    form: Result<Form<Vec<(String, String)>>, FormRejection>,
) -> Response {
    let fields = match form_fields(form) {
        Ok(f) => f,
        Err(e) => return e.into_page(),
    };
    let identity = match identify(&state, &headers).await {
        Ok(i) => i,
        Err(e) => return e.into_page(),
    };
    if let Identity::Session(session) = &identity {
        if let Err(e) = writer(&identity, field(&fields, "csrf")) {
            return e.into_page();
        }
        if let Some(value) = cookie(&headers, SESSION_COOKIE) {
            state.sessions.end(&value);
        }
        tracing::info!("http: {} logged out", session.user);
    }
    let mut response = see_other("/");
    let gone = set_cookie(SESSION_COOKIE, "", "/", 0, state.secure_cookies);
    if let Ok(v) = HeaderValue::from_str(&gone) {
        response.headers_mut().append(header::SET_COOKIE, v);
    }
    response
}

/// `GET /library`: the references as recorded, with their labels and
/// state, and the calibration's state.
pub(super) async fn library(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    uri: Uri,
) -> Response {
    let identity = match reader(&state, &headers, &uri).await {
        Ok(i) => i,
        Err(r) => return r,
    };
    let refs = match state.pool.run(|store| store.references()).await {
        Ok(r) => r,
        Err(e) => return e.into_page(),
    };
    let ranks: Vec<String> = if state.ranks.is_empty() {
        let mut all: Vec<String> = refs.iter().flat_map(|r| r.labels.keys().cloned()).collect();
        all.sort();
        all.dedup();
        all
    } else {
        state.ranks.clone()
    };
    let live = state.live.snapshot();
    let prepared = refs
        .iter()
        .filter(|r| r.state == crate::store::ReferenceState::Prepared)
        .count();
    let mut body = format!(
        "<p id=\"summary\">{} references, {prepared} prepared; calibration: <b id=\"calibration\">{}</b></p>\n\
         <table id=\"references\"><tr><th>Name</th>",
        refs.len(),
        escape(if live.calibration.is_empty() { "unknown (no daemon)" } else { &live.calibration }),
    );
    for rank in &ranks {
        let _ = write!(body, "<th>{}</th>", escape(rank));
    }
    body.push_str("<th>State</th><th>Prepared</th><th>SHA-256</th></tr>\n");
    for r in &refs {
        let _ = write!(body, "<tr><td>{}</td>", escape(&r.name));
        for rank in &ranks {
            let taxon = r.labels.get(rank).cloned().flatten().unwrap_or_default();
            let _ = write!(body, "<td>{}</td>", escape(&taxon));
        }
        let state_text = match &r.error {
            Some(e) => format!("<span class=\"bad\">{}: {}</span>", r.state, escape(e)),
            None => r.state.to_string(),
        };
        let _ = writeln!(
            body,
            "<td>{state_text}</td><td>{}</td><td><code>{}</code></td></tr>",
            r.prepared_at_ms.map(utc_time).unwrap_or_default(),
            escape(r.content_hash.get(..12).unwrap_or(&r.content_hash)),
        );
    }
    body.push_str("</table>\n");
    html_response(StatusCode::OK, page("library", &identity, &body))
}

/// `GET /status`: the daemon's state.
pub(super) async fn status(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    uri: Uri,
) -> Response {
    let identity = match reader(&state, &headers, &uri).await {
        Ok(i) => i,
        Err(r) => return r,
    };
    let counts = match state.pool.run(|store| store.counts()).await {
        Ok(c) => c,
        Err(e) => return e.into_page(),
    };
    let live = state.live.snapshot();
    let row = |k: &str, v: String| format!("<tr><th>{k}</th><td>{v}</td></tr>\n");
    let mut body = String::from("<table id=\"daemon\">\n");
    body.push_str(&row(
        "Daemon",
        if live.running {
            format!("running: {}", escape(&live.status_line))
        } else {
            "<span class=\"bad\">not running</span>".into()
        },
    ));
    body.push_str(&row(
        "Identifying",
        live.current_scan.map_or("nothing".into(), |id| {
            format!("<a href=\"/scans/{id}\">scan {id}</a>")
        }),
    ));
    body.push_str(&row(
        "Queue",
        format!("<span id=\"queue\">{}</span> pending", counts.pending),
    ));
    body.push_str(&row(
        "Storage",
        match &live.degraded {
            Some(d) => format!("<b class=\"bad\" id=\"degraded\">{}</b>", escape(d)),
            None => "<span class=\"ok\" id=\"degraded\">healthy</span>".into(),
        },
    ));
    body.push_str(&row("References", live.references.to_string()));
    body.push_str(&row("Calibration", escape(&live.calibration)));
    body.push_str(&row(
        "Serial line",
        match &live.serial {
            Some(s) => format!(
                "{} at {} baud, trigger <code>{}</code>",
                escape(&s.port),
                s.baud,
                escape(&s.trigger)
            ),
            None => "none configured".into(),
        },
    ));
    body.push_str(&row(
        "Export folder",
        format!("<code>{}</code>", escape(&live.watching)),
    ));
    body.push_str(&row(
        "Library",
        format!("<code>{}</code>", escape(&live.library)),
    ));
    body.push_str(&row(
        "Scans",
        format!(
            "{} ok, {} error, {} duplicate, {} superseded, {} running, {} pending",
            counts.ok,
            counts.error,
            counts.duplicate,
            counts.superseded,
            counts.running,
            counts.pending
        ),
    ));
    if live.updated_at_ms > 0 {
        body.push_str(&row("Updated", utc_time(live.updated_at_ms)));
    }
    body.push_str("</table>\n");
    html_response(StatusCode::OK, page("daemon", &identity, &body))
}

/// `GET /api/v1/session`: `{"user", "csrf"}` of the request's session
/// (nulls without one): how a page's script finds its CSRF token.
pub(super) async fn session(State(state): State<Arc<AppState>>, headers: HeaderMap) -> Response {
    match identify(&state, &headers).await {
        Ok(identity) => axum::Json(serde_json::json!({
            "user": identity.user(),
            "csrf": identity.csrf(),
        }))
        .into_response(),
        Err(e) => e.into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_local_paths_are_gone_back_to() {
        assert_eq!(safe_next(Some("/scans/3?x=1")), "/scans/3?x=1");
        for bad in [
            "//evil.example/",
            "https://evil.example/",
            "/\\evil",
            "x",
            "/a b",
        ] {
            assert_eq!(safe_next(Some(bad)), "/", "{bad}");
        }
        assert_eq!(safe_next(None), "/");
    }

    #[test]
    fn injected_parts_go_inside_the_body() {
        let html = "<html><body>\n<h1>x</h1></body></html>";
        assert_eq!(
            inject(html, "TOP", "END"),
            "<html><body>\nTOP\n<h1>x</h1>END</body></html>"
        );
    }
}
