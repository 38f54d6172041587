// Whether the dashboard is signed in: the coordinator's API wants its client token, which
// the browser holds as an HttpOnly session cookie after signing in (docs/API.md,
// "Authentication"). The page cannot read that cookie, so it asks the server, and any 401
// later (a restarted coordinator with a new token) brings the sign-in view back.
import { ApiError } from "./api";

/** Where an operator finds the token: DATA is the coordinator's --data directory. */
export const TOKEN_FILE = "DATA/client.token";

/** What the sign-in form says when a sign-in fails. */
export function signInFailure(e: unknown): string {
  if (e instanceof ApiError && e.status === 401) return `That is not the client token: copy it from ${TOKEN_FILE} on the coordinator's machine.`;
  if (e instanceof ApiError && e.status === 403)
    return "That is the worker token: the dashboard needs the client token.";
  return `cannot sign in: ${(e as Error).message}`;
}

export interface SessionViews {
  showDashboard(): void;
  showSignIn(message?: string): void;
}

export type SessionState = "checking" | "signed-in" | "signed-out";

/** Switches between the dashboard and the sign-in view, each once per change. */
export class SessionGate {
  state: SessionState = "checking";

  constructor(private readonly views: SessionViews) {}

  /**
   * Asks the server. Only a 401 means signed out: any other failure (a server that is down
   * or busy) leaves the pages to show their own errors, as before there was a sign-in.
   */
  async check(ask: () => Promise<unknown>): Promise<void> {
    try {
      await ask();
    } catch (e) {
      if (e instanceof ApiError && e.status === 401) {
        this.signedOut();
        return;
      }
    }
    this.signedIn();
  }

  signedIn(): void {
    if (this.state === "signed-in") return;
    this.state = "signed-in";
    this.views.showDashboard();
  }

  signedOut(message?: string): void {
    if (this.state === "signed-out") return;
    this.state = "signed-out";
    this.views.showSignIn(message);
  }
}
