// The banner that says the coordinator cannot write its run record (a full disk): shown
// on every page while the server reports a storage warning, from the live stream's
// greeting and its "storage" events.
import type { LiveEvent } from "./live";

/** The part of an element the banner touches; tests pass a plain object. */
export interface BannerElement {
  hidden: boolean;
  textContent: string | null;
}

export class StorageBanner {
  constructor(private readonly el: BannerElement) {
    this.show("");
  }

  onEvent(e: LiveEvent): void {
    if (e.type === "hello") this.show(e.storage_warning ?? "");
    else if (e.type === "storage") this.show(e.storage_warning);
  }

  show(warning: string): void {
    const text = warning ? `The coordinator cannot write its record (renders go on; it keeps retrying): ${warning}` : "";
    if (this.el.textContent !== text) this.el.textContent = text;
    this.el.hidden = !warning;
  }
}
