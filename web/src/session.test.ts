import { afterEach, describe, expect, it, vi } from "vitest";
import { api, ApiError, onUnauthenticated } from "./api";
import { SessionGate, signInFailure } from "./session";

function recordingGate() {
  const shown: string[] = [];
  const gate = new SessionGate({
    showDashboard: () => shown.push("dashboard"),
    showSignIn: (message) => shown.push(`sign-in${message ? `: ${message}` : ""}`),
  });
  return { gate, shown };
}

describe("SessionGate", () => {
  it("shows the dashboard when the server answers, the sign-in view on 401", async () => {
    const { gate, shown } = recordingGate();
    await gate.check(async () => ({ signed_in: true }));
    expect(gate.state).toBe("signed-in");
    await gate.check(() => Promise.reject(new ApiError("needs the client token", 401)));
    expect(gate.state).toBe("signed-out");
    expect(shown).toEqual(["dashboard", "sign-in"]);
  });

  it("leaves other failures to the pages: a busy or absent server is no reason to sign in", async () => {
    const { gate, shown } = recordingGate();
    await gate.check(() => Promise.reject(new ApiError("too many streams", 503)));
    await gate.check(() => Promise.reject(new TypeError("Failed to fetch")));
    expect(gate.state).toBe("signed-in");
    expect(shown).toEqual(["dashboard"]);
  });

  it("switches views once per change, however many requests are refused", () => {
    const { gate, shown } = recordingGate();
    gate.signedOut();
    gate.signedOut();
    gate.signedIn();
    gate.signedIn();
    gate.signedOut("cannot sign out: offline");
    expect(shown).toEqual(["sign-in", "dashboard", "sign-in: cannot sign out: offline"]);
  });
});

describe("signInFailure", () => {
  it("says where the client token is, and which token was given", () => {
    expect(signInFailure(new ApiError("x", 401))).toContain("DATA/client.token");
    expect(signInFailure(new ApiError("x", 403))).toContain("worker token");
    expect(signInFailure(new ApiError("request body too large", 413))).toContain("request body too large");
  });
});

describe("onUnauthenticated", () => {
  afterEach(() => {
    vi.unstubAllGlobals();
    onUnauthenticated(() => {});
  });
  const answer = (status: number) =>
    vi.fn(async () => new Response(JSON.stringify({ error: "refused" }), { status, headers: { "Content-Type": "application/json" } }));

  it("runs on every 401 and on nothing else", async () => {
    let signedOut = 0;
    onUnauthenticated(() => signedOut++);
    vi.stubGlobal("fetch", answer(401));
    await expect(api.renders()).rejects.toMatchObject({ status: 401, message: "refused" });
    await expect(api.signIn("wrong")).rejects.toMatchObject({ status: 401 });
    expect(signedOut).toBe(2);
    for (const status of [403, 404, 503]) {
      vi.stubGlobal("fetch", answer(status));
      await expect(api.workers()).rejects.toMatchObject({ status });
    }
    expect(signedOut).toBe(2);
  });

  it("signs in and out with JSON requests the server's cross-site checks accept", async () => {
    const fetch = vi.fn(async () => new Response('{"ok":true}', { status: 200 }));
    vi.stubGlobal("fetch", fetch);
    await api.signIn("the-token");
    await api.signOut();
    const calls = fetch.mock.calls as unknown as [string, RequestInit][];
    expect(calls.map(([url, init]) => [url, init.method])).toEqual([
      ["/api/session", "POST"],
      ["/api/session", "DELETE"],
    ]);
    for (const [, init] of calls) expect((init.headers as Record<string, string>)["Content-Type"]).toBe("application/json");
    expect(JSON.parse(String(calls[0][1].body))).toEqual({ token: "the-token" });
  });
});
