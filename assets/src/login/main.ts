/**
 * Login page: `POST /api/login` with name and password; the token goes to `localStorage` and
 * the browser back to the page that sent it here (`?next=`, default the operator page). In
 * local mode the server needs no login and the page says so.
 */

import { AuthError, TOKEN_KEY, fetchSession, login, nextPath } from "../lib/session";

function byId<T extends HTMLElement>(id: string, type: new () => T): T {
  const el = document.getElementById(id);
  if (!(el instanceof type)) throw new Error(`login page: #${id} is missing from login.html`);
  return el;
}

function main(): void {
  const params = new URLSearchParams(window.location.search);
  const form = byId("login-form", HTMLFormElement);
  const name = byId("login-name", HTMLInputElement);
  const password = byId("login-password", HTMLInputElement);
  const submit = byId("login-submit", HTMLButtonElement);
  const message = byId("message", HTMLElement);
  const banner = byId("mode-banner", HTMLElement);
  const next = nextPath(params);

  const show = (text: string, kind: "info" | "warn" | "error"): void => {
    message.textContent = text;
    message.dataset["kind"] = kind;
  };

  const reason = params.get("reason");
  if (reason) show(`Please log in again (${reason}).`, "warn");

  fetchSession(null)
    .then((session) => {
      if (session.mode === "local") {
        banner.hidden = false;
        banner.dataset["mode"] = "local";
        banner.textContent = "Local mode: this server needs no login — anyone on this computer may pilot.";
        form.hidden = true;
        show("No login needed here.", "info");
      } else if (session.anonymous_observers) {
        banner.hidden = false;
        banner.dataset["mode"] = "secure";
        banner.textContent = "You may also watch without logging in.";
      }
    })
    .catch(() => undefined);

  form.addEventListener("submit", (event) => {
    event.preventDefault();
    submit.disabled = true;
    show("Logging in…", "info");
    login(name.value.trim(), password.value)
      .then((result) => {
        window.localStorage.setItem(TOKEN_KEY, result.token);
        show(`Welcome, ${result.user.name}.`, "info");
        window.location.assign(next);
      })
      .catch((err: unknown) => {
        password.value = "";
        const text = err instanceof AuthError || err instanceof Error ? err.message : String(err);
        show(text, "error");
      })
      .finally(() => {
        submit.disabled = false;
      });
  });
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", main, { once: true });
} else {
  main();
}
