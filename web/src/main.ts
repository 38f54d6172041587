// The dashboard: hash routes to pages, one live-update stream shared by all of them; the
// sign-in view instead while the API answers 401.
import "./style.css";
import { api, onUnauthenticated } from "./api";
import { Live } from "./live";
import { ComparePage } from "./pages/compare";
import type { Page } from "./pages/page";
import { RenderPage } from "./pages/render";
import { RendersPage } from "./pages/renders";
import { SignInPage } from "./pages/signin";
import { StudiesPage } from "./pages/studies";
import { WorkersPage } from "./pages/workers";
import { SessionGate } from "./session";
import { StorageBanner } from "./storage";

const app = document.getElementById("app")!;
const liveBadge = document.getElementById("live")!;
const live = new Live();
const storage = new StorageBanner(document.getElementById("storage-warning")!);
let page: Page | null = null;

function route(): Page {
  const hash = location.hash.replace(/^#\/?/, "");
  const [path, query = ""] = hash.split("?");
  const parts = path.split("/").filter(Boolean).map(decodeURIComponent);
  switch (parts[0]) {
    case "render":
      if (parts[1]) return new RenderPage(parts[1]);
      break;
    case "compare":
      return new ComparePage(new URLSearchParams(query));
    case "workers":
      return new WorkersPage();
    case "studies":
      return new StudiesPage(parts[1], parts[2]);
  }
  return new RendersPage(new URLSearchParams(query));
}

function show(): void {
  page?.dispose?.();
  page = route();
  app.replaceChildren(page.el);
  const first = location.hash.replace(/^#\/?/, "").split(/[/?]/)[0];
  const section = !first || first === "render" ? "renders" : first;
  for (const a of document.querySelectorAll<HTMLAnchorElement>("nav a"))
    a.classList.toggle("active", a.dataset.nav === section);
}

live.onStatus = (s) => {
  liveBadge.dataset.status = s;
  liveBadge.textContent = s === "live" ? "live" : s === "connecting" ? "connecting…" : "reconnecting…";
};
live.subscribe((e) => storage.onEvent(e));
live.subscribe((e) => page?.onEvent?.(e));

const gate = new SessionGate({
  showDashboard() {
    document.body.dataset.session = "signed-in";
    show();
    live.start();
  },
  showSignIn(message) {
    document.body.dataset.session = "signed-out";
    live.stop();
    storage.show("");
    page?.dispose?.();
    page = new SignInPage(() => gate.signedIn(), message);
    app.replaceChildren(page.el);
    page.el.querySelector("input")?.focus();
  },
});
onUnauthenticated(() => gate.signedOut());
live.onRefused = () => void gate.check(api.session);

document.getElementById("sign-out")!.addEventListener("click", async () => {
  try {
    await api.signOut();
    gate.signedOut();
  } catch (e) {
    gate.signedOut(`cannot sign out: ${(e as Error).message}`);
  }
});
window.addEventListener("hashchange", () => {
  if (gate.state === "signed-in") show();
});
void gate.check(api.session);
