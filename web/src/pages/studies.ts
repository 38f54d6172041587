// Studies: the reports `aliquot study` writes (report.md with its charts and tables),
// found in the coordinator's data directory and the source tree's docs/studies.
import { api, type Study } from "../api";
import { clear, h } from "../dom";
import { renderMarkdown } from "../markdown";
import type { Page } from "./page";

const IMAGE = /\.(png|jpe?g|svg)$/i;

export class StudiesPage implements Page {
  el = h("section", { class: "page studies-page" });

  constructor(private readonly source?: string, private readonly name?: string) {
    void this.load();
  }

  private async load(): Promise<void> {
    clear(this.el);
    let studies: Study[];
    try {
      studies = (await api.studies()).studies;
    } catch (e) {
      this.el.append(h("h1", {}, "Studies"), h("p", { class: "error" }, (e as Error).message));
      return;
    }
    const study = studies.find((s) => s.source === this.source && s.name === this.name);
    if (study) await this.showStudy(study);
    else this.showList(studies);
  }

  private showList(studies: Study[]): void {
    this.el.append(h("h1", {}, "Studies"));
    if (!studies.length) {
      this.el.append(
        h(
          "p",
          { class: "muted empty", id: "no-studies" },
          "No studies yet. ",
          h("code", {}, "aliquot study"),
          " writes its reports (report.md, charts, tables) into the data directory's studies/ folder; they appear here.",
        ),
      );
      return;
    }
    this.el.append(
      h(
        "ul",
        { class: "study-list", id: "study-list" },
        ...studies.map((s) =>
          h(
            "li",
            { class: "card" },
            h("a", { href: `#/studies/${encodeURIComponent(s.source)}/${encodeURIComponent(s.name)}` }, s.title),
            h("span", { class: "muted" }, ` ${s.source}/${s.name} · ${s.files.length} files`),
          ),
        ),
      ),
    );
  }

  private async showStudy(s: Study): Promise<void> {
    this.el.append(h("p", { class: "crumbs" }, h("a", { href: "#/studies" }, "Studies"), ` / ${s.source}/${s.name}`));
    const body = h("article", { class: "card report", id: "study-report" });
    this.el.append(body);
    const resolve = (path: string) => api.studyFileUrl(s, path.replace(/^\.\//, ""));
    let referenced = "";
    try {
      const res = await fetch(api.studyFileUrl(s, s.report), { cache: "no-cache" });
      referenced = await res.text();
      body.append(renderMarkdown(referenced, { resolve }));
    } catch (e) {
      body.append(h("h1", {}, s.title), h("p", { class: "error" }, (e as Error).message));
    }
    // Charts the report does not show itself, then every file.
    const extra = s.files.filter((f) => IMAGE.test(f) && !referenced.includes(f));
    if (extra.length)
      this.el.append(
        h("div", { class: "gallery" }, ...extra.map((f) => h("figure", { class: "card" }, h("img", { src: resolve(f), alt: f, loading: "lazy" }), h("figcaption", {}, f)))),
      );
    this.el.append(
      h("h2", {}, "Files"),
      h("ul", { class: "files" }, ...s.files.map((f) => h("li", {}, h("a", { href: resolve(f), target: "_blank" }, f)))),
    );
  }
}
