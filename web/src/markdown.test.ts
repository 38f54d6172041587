import { describe, expect, it } from "vitest";
import { parseBlocks } from "./markdown";

describe("markdown blocks", () => {
  it("splits a study report into headings, paragraphs, tables, lists and code", () => {
    const blocks = parseBlocks(
      [
        "# Equal budget",
        "",
        "Uniform vs adaptive at",
        "the same budget.",
        "",
        "| method | E |",
        "|---|--:|",
        "| uniform | 0.012 |",
        "| adaptive | 0.009 |",
        "",
        "- one",
        "- two",
        "",
        "```",
        "aliquot study",
        "```",
      ].join("\n"),
    );
    expect(blocks.map((b) => b.kind)).toEqual(["heading", "paragraph", "table", "list", "code"]);
    expect(blocks[1]).toEqual({ kind: "paragraph", text: "Uniform vs adaptive at the same budget." });
    const table = blocks[2] as { head: string[]; rows: string[][]; align: string[] };
    expect(table.head).toEqual(["method", "E"]);
    expect(table.rows).toEqual([
      ["uniform", "0.012"],
      ["adaptive", "0.009"],
    ]);
    expect(table.align).toEqual(["", "right"]);
  });
});
