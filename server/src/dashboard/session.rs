//! Signing in to the dashboard: `POST /signin` takes the client token and sets an HttpOnly cookie
//! (axum-extra's cookie jar) holding a random session id, never the token, stored server-side as
//! its SHA-256 with an expiry; `POST /signout` revokes it. The form is decoded by axum's `Form`
//! and the token compared in constant time ([`crate::Secret`]).

use std::fmt::Write as _;

use axum::Form;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{Html, IntoResponse, Response};
use axum_extra::extract::cookie::{Cookie, CookieJar, SameSite};
use cryofit_plots::escape_html as esc;

use super::{SESSION_COOKIE, db_error, page};
use crate::clock::now_ms;
use crate::db;
use crate::state::AppState;

pub(super) fn secured(state: &AppState) -> bool {
    state.settings.client_token.is_some() || state.settings.worker_token.is_some()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of a session id, hex: what the database holds.
fn digest(session: &str) -> String {
    use sha2::Digest as _;
    hex(&sha2::Sha256::digest(session.as_bytes()))
}

/// The session id of the cookie, if it is one that is stored and not expired.
async fn session(state: &AppState, headers: &HeaderMap) -> Option<String> {
    let id = CookieJar::from_headers(headers).get(SESSION_COOKIE)?.value().to_string();
    if id.len() != 64 || !id.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    match db::session_valid(state.coordinator.db().reader(), &digest(&id), now_ms()).await {
        Ok(true) => Some(id),
        Ok(false) => None,
        Err(e) => {
            tracing::error!(error = %e, "reading a session");
            None
        }
    }
}

pub(super) async fn signed_in(state: &AppState, headers: &HeaderMap) -> bool {
    !secured(state) || session(state, headers).await.is_some()
}

pub(super) async fn require_session(State(state): State<AppState>, req: Request, next: Next) -> Response {
    if signed_in(&state, req.headers()).await {
        return next.run(req).await;
    }
    let next_path = req.uri().path().to_string();
    let body = sign_in_form(Some("Sign in with the client token to see this page."), &next_path);
    (StatusCode::UNAUTHORIZED, Html(page("Sign in", &body, false, true))).into_response()
}

pub(super) fn sign_in_form(note: Option<&str>, next_path: &str) -> String {
    let mut s = String::from("<h1>cryofit coordinator</h1>");
    if let Some(n) = note {
        let _ = write!(s, "<p class=\"note\">{}</p>", esc(n));
    }
    let _ = write!(
        s,
        "<form method=\"post\" action=\"/signin\" class=\"signin\"><input type=\"hidden\" name=\"next\" value=\"{}\">\
         <label>Client token <input name=\"token\" type=\"password\" autocomplete=\"current-password\" required></label> \
         <button type=\"submit\">Sign in</button></form>\
         <p>The REST API is under <code>/api/v1</code> (bearer token); its contract is \
         <code>/api/v1/openapi.json</code>.</p>",
        esc(next_path)
    );
    s
}

/// Where to go after signing in: a local path, `/` otherwise. Whitespace and control characters
/// are refused (browsers drop a TAB or a newline from a URL, which would turn `/\t/host` into
/// `//host`), as are backslashes and `//` (another host).
fn local_path(next: Option<&str>) -> String {
    match next {
        Some(p)
            if p.starts_with('/')
                && !p.starts_with("//")
                && !p.chars().any(|c| c.is_control() || c.is_whitespace() || c == '\\') =>
        {
            p.to_string()
        }
        _ => "/".into(),
    }
}

fn see_other(location: &str, jar: CookieJar) -> Response {
    let mut r = (jar, StatusCode::SEE_OTHER).into_response();
    if let Ok(v) = HeaderValue::from_str(location) {
        r.headers_mut().insert(header::LOCATION, v);
    }
    r
}

/// The sign-in form's fields.
#[derive(Debug, serde::Deserialize)]
pub(super) struct SignIn {
    #[serde(default)]
    token: String,
    #[serde(default)]
    next: Option<String>,
}

fn session_cookie(state: &AppState, value: String, max_age: cookie::time::Duration) -> Cookie<'static> {
    Cookie::build((SESSION_COOKIE, value))
        .path("/")
        .http_only(true)
        .same_site(SameSite::Strict)
        .secure(state.settings.secure_cookies)
        .max_age(max_age)
        .build()
}

pub(super) async fn sign_in(State(state): State<AppState>, jar: CookieJar, Form(form): Form<SignIn>) -> Response {
    let next = local_path(form.next.as_deref());
    if !secured(&state) {
        return see_other(&next, jar);
    }
    let token = form.token.trim();
    let valid = !token.is_empty() && state.settings.client_token.as_ref().is_some_and(|t| t.matches(token));
    if !valid {
        let body = sign_in_form(Some("That is not the client token (CRYOFIT_CLIENT_TOKEN)."), &next);
        return (StatusCode::UNAUTHORIZED, Html(page("Sign in", &body, false, true))).into_response();
    }
    let id = hex(&rand::random::<[u8; 32]>());
    let now = now_ms();
    let ttl = state.settings.session_ttl;
    let db = state.coordinator.db();
    let stored = async {
        let mut tx = db.begin().await?;
        db::delete_expired_sessions(&mut tx, now).await?;
        db::insert_session(&mut tx, &digest(&id), now, now + ttl.as_millis() as i64).await?;
        db.commit(tx).await
    };
    if let Err(e) = stored.await {
        return db_error(&state, e);
    }
    let max_age = cookie::time::Duration::seconds(i64::try_from(ttl.as_secs()).unwrap_or(i64::MAX));
    see_other(&next, jar.add(session_cookie(&state, id, max_age)))
}

pub(super) async fn sign_out(State(state): State<AppState>, jar: CookieJar) -> Response {
    if let Some(id) = jar.get(SESSION_COOKIE).map(|c| c.value().to_string()) {
        let db = state.coordinator.db();
        let done = async {
            let mut tx = db.begin().await?;
            db::delete_session(&mut tx, &digest(&id)).await?;
            db.commit(tx).await
        };
        if let Err(e) = done.await {
            return db_error(&state, e);
        }
    }
    see_other("/", jar.remove(session_cookie(&state, String::new(), cookie::time::Duration::ZERO)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_in_goes_only_to_local_paths() {
        assert_eq!(local_path(Some("//evil.example")), "/");
        assert_eq!(local_path(Some("/calibrations/3")), "/calibrations/3");
        assert_eq!(local_path(None), "/");
        // browsers drop TAB, CR and LF from URLs: `/\t/evil.example` would become `//evil.example`
        assert_eq!(local_path(Some("/\t/evil.example")), "/");
        assert_eq!(local_path(Some("/\n/evil.example")), "/");
        assert_eq!(local_path(Some("/ /evil.example")), "/");
        assert_eq!(local_path(Some("/\\evil.example")), "/");
        assert_eq!(local_path(Some("/\u{0}x")), "/");
    }

    #[test]
    fn session_ids_are_stored_as_digests() {
        let id = hex(&[0xab; 32]);
        assert_eq!(id.len(), 64);
        assert_eq!(digest(&id).len(), 64);
        assert_ne!(digest(&id), id);
        // SHA-256 of "abc"
        assert_eq!(digest("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }
}
