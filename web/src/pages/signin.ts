// Sign-in: what the dashboard shows instead of an error while the API answers 401. The
// token goes to POST /api/session once; the browser keeps it as an HttpOnly cookie.
import { api } from "../api";
import { h } from "../dom";
import { signInFailure, TOKEN_FILE } from "../session";
import type { Page } from "./page";

export class SignInPage implements Page {
  el = h("section", { class: "page sign-in-page" });
  private token = h("input", {
    type: "password",
    id: "sign-in-token",
    name: "token",
    autocomplete: "current-password",
    required: true,
    size: 40,
  });
  private button = h("button", { type: "submit", id: "sign-in-button" }, "Sign in");
  private message = h("p", { class: "form-message", id: "sign-in-message", role: "status" });

  constructor(
    private readonly onSignedIn: () => void,
    message = "",
  ) {
    const form = h(
      "form",
      { class: "card sign-in-form", id: "sign-in-form" },
      h("h1", {}, "Sign in"),
      h(
        "p",
        { id: "sign-in-where" },
        "This coordinator wants its client token. It is in ",
        h("code", {}, TOKEN_FILE),
        " on the coordinator's machine (DATA is the coordinator's --data directory).",
      ),
      h("div", { class: "form-row" }, h("label", {}, "client token", this.token), this.button),
      this.message,
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      void this.submit();
    });
    this.el.append(form);
    this.setMessage(message, true);
  }

  private async submit(): Promise<void> {
    this.button.disabled = true;
    this.setMessage("", false);
    try {
      await api.signIn(this.token.value.trim());
      this.token.value = "";
      this.onSignedIn();
    } catch (e) {
      this.setMessage(signInFailure(e), true);
      this.token.select();
    } finally {
      this.button.disabled = false;
    }
  }

  private setMessage(text: string, error: boolean): void {
    this.message.textContent = text;
    this.message.classList.toggle("error", error);
  }
}
