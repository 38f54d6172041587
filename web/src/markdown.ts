// A small Markdown renderer for study reports: headings, paragraphs, lists, tables, fenced
// code, emphasis, inline code, links and images. It builds DOM nodes (never HTML strings),
// so a report cannot inject markup; relative links and images go through `resolve`.

export interface MarkdownOptions {
  resolve: (path: string) => string;
}

type Block =
  | { kind: "heading"; level: number; text: string }
  | { kind: "code"; text: string }
  | { kind: "list"; ordered: boolean; items: string[] }
  | { kind: "table"; head: string[]; rows: string[][]; align: string[] }
  | { kind: "paragraph"; text: string };

const isTableDivider = (line: string) => /^\s*\|?\s*:?-{2,}:?\s*(\|\s*:?-{2,}:?\s*)*\|?\s*$/.test(line);
const cells = (line: string) =>
  line
    .trim()
    .replace(/^\|/, "")
    .replace(/\|$/, "")
    .split("|")
    .map((c) => c.trim());

export function parseBlocks(text: string): Block[] {
  const lines = text.replace(/\r\n?/g, "\n").split("\n");
  const blocks: Block[] = [];
  let i = 0;
  while (i < lines.length) {
    const line = lines[i];
    if (!line.trim()) {
      i++;
      continue;
    }
    const heading = /^(#{1,6})\s+(.*?)\s*#*\s*$/.exec(line);
    if (heading) {
      blocks.push({ kind: "heading", level: heading[1].length, text: heading[2] });
      i++;
      continue;
    }
    if (/^\s*```/.test(line)) {
      const body: string[] = [];
      i++;
      while (i < lines.length && !/^\s*```/.test(lines[i])) body.push(lines[i++]);
      i++;
      blocks.push({ kind: "code", text: body.join("\n") });
      continue;
    }
    if (line.includes("|") && i + 1 < lines.length && isTableDivider(lines[i + 1])) {
      const head = cells(line);
      const align = cells(lines[i + 1]).map((c) =>
        c.startsWith(":") && c.endsWith(":") ? "center" : c.endsWith(":") ? "right" : "",
      );
      i += 2;
      const rows: string[][] = [];
      while (i < lines.length && lines[i].includes("|") && lines[i].trim()) rows.push(cells(lines[i++]));
      blocks.push({ kind: "table", head, rows, align });
      continue;
    }
    const item = /^\s*([-*+]|\d+[.)])\s+(.*)$/.exec(line);
    if (item) {
      const ordered = /\d/.test(item[1]);
      const items: string[] = [];
      while (i < lines.length) {
        const m = /^\s*([-*+]|\d+[.)])\s+(.*)$/.exec(lines[i]);
        if (m) items.push(m[2]);
        else if (lines[i].trim() && /^\s{2,}/.test(lines[i])) items[items.length - 1] += " " + lines[i].trim();
        else break;
        i++;
      }
      blocks.push({ kind: "list", ordered, items });
      continue;
    }
    const para: string[] = [];
    while (
      i < lines.length &&
      lines[i].trim() &&
      !/^(#{1,6})\s/.test(lines[i]) &&
      !/^\s*```/.test(lines[i]) &&
      !/^\s*([-*+]|\d+[.)])\s+/.test(lines[i]) &&
      !(lines[i].includes("|") && i + 1 < lines.length && isTableDivider(lines[i + 1]))
    )
      para.push(lines[i++].trim());
    blocks.push({ kind: "paragraph", text: para.join(" ") });
  }
  return blocks;
}

const INLINE = /(!?)\[([^\]]*)\]\(([^)\s]+)(?:\s+"[^"]*")?\)|`([^`]+)`|\*\*([^*]+)\*\*|__([^_]+)__|\*([^*]+)\*|_([^_\s][^_]*)_/;

function isExternal(url: string): boolean {
  return /^[a-z][a-z0-9+.-]*:/i.test(url) || url.startsWith("/") || url.startsWith("#");
}

export function renderInline(text: string, parent: Node, opts: MarkdownOptions): void {
  let rest = text;
  while (rest) {
    const m = INLINE.exec(rest);
    if (!m) {
      parent.appendChild(document.createTextNode(rest));
      return;
    }
    if (m.index > 0) parent.appendChild(document.createTextNode(rest.slice(0, m.index)));
    rest = rest.slice(m.index + m[0].length);
    if (m[3] !== undefined) {
      const url = m[3];
      const target = isExternal(url) ? url : opts.resolve(url);
      if (/^javascript:/i.test(url)) {
        parent.appendChild(document.createTextNode(m[2]));
      } else if (m[1]) {
        const img = document.createElement("img");
        img.src = target;
        img.alt = m[2];
        img.loading = "lazy";
        parent.appendChild(img);
      } else {
        const a = document.createElement("a");
        a.href = target;
        renderInline(m[2], a, opts);
        parent.appendChild(a);
      }
    } else if (m[4] !== undefined) {
      const code = document.createElement("code");
      code.textContent = m[4];
      parent.appendChild(code);
    } else {
      const strong = m[5] ?? m[6];
      const el = document.createElement(strong !== undefined ? "strong" : "em");
      renderInline(strong ?? m[7] ?? m[8], el, opts);
      parent.appendChild(el);
    }
  }
}

export function renderMarkdown(text: string, opts: MarkdownOptions): DocumentFragment {
  const out = document.createDocumentFragment();
  for (const b of parseBlocks(text)) {
    if (b.kind === "heading") {
      const el = document.createElement(`h${b.level}` as "h1");
      renderInline(b.text, el, opts);
      out.appendChild(el);
    } else if (b.kind === "code") {
      const pre = document.createElement("pre");
      const code = document.createElement("code");
      code.textContent = b.text;
      pre.appendChild(code);
      out.appendChild(pre);
    } else if (b.kind === "list") {
      const list = document.createElement(b.ordered ? "ol" : "ul");
      for (const item of b.items) {
        const li = document.createElement("li");
        renderInline(item, li, opts);
        list.appendChild(li);
      }
      out.appendChild(list);
    } else if (b.kind === "table") {
      const table = document.createElement("table");
      const thead = table.createTHead().insertRow();
      b.head.forEach((c, k) => {
        const th = document.createElement("th");
        if (b.align[k]) th.style.textAlign = b.align[k];
        renderInline(c, th, opts);
        thead.appendChild(th);
      });
      const body = table.createTBody();
      for (const row of b.rows) {
        const tr = body.insertRow();
        row.forEach((c, k) => {
          const td = tr.insertCell();
          if (b.align[k]) td.style.textAlign = b.align[k];
          renderInline(c, td, opts);
        });
      }
      const wrap = document.createElement("div");
      wrap.className = "table-wrap";
      wrap.appendChild(table);
      out.appendChild(wrap);
    } else {
      const p = document.createElement("p");
      renderInline(b.text, p, opts);
      out.appendChild(p);
    }
  }
  return out;
}
