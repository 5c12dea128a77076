#!/usr/bin/env python3
"""Checks the Markdown links of the README, ARCHITECTURE.md, the manual (docs/src) and the
READMEs beside scenes and benches: every relative link names a file that exists, every
#anchor a heading of its page, and the manual's SUMMARY.md lists every page of the book.
Prints each broken link with its file and line; exits 1 if there is one.

    python3 docs/check-links.py
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINK = re.compile(r'!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+"[^"]*")?\)')


def pages():
    found = [os.path.join(ROOT, 'README.md'), os.path.join(ROOT, 'ARCHITECTURE.md')]
    for top in ('docs/src', 'scenes', 'benches', 'deploy'):
        for folder, _, files in os.walk(os.path.join(ROOT, top)):
            found += [os.path.join(folder, f) for f in files if f.endswith('.md')]
    return sorted(found)


def slug(heading):
    """The anchor GitHub and mdBook give a heading."""
    text = re.sub(r'`|\*|_(?=\w)|(?<=\w)_', '', heading).strip().lower()
    text = re.sub(r'[^\w\- ]', '', text)
    return text.replace(' ', '-')


def anchors(path):
    out = set()
    fence = False
    for line in open(path, encoding='utf-8'):
        if line.startswith('```'):
            fence = not fence
        m = re.match(r'^(#+)\s+(.*?)\s*#*\s*$', line)
        if m and not fence:
            out.add(slug(m.group(2)))
    return out


def links(path):
    fence = False
    for n, line in enumerate(open(path, encoding='utf-8'), 1):
        if line.startswith('```'):
            fence = not fence
            continue
        if fence:
            continue
        # Inline code cannot hold a link.
        for m in LINK.finditer(re.sub(r'`[^`]*`', '', line)):
            yield n, m.group(1)


def main():
    broken = []
    for page in pages():
        rel = os.path.relpath(page, ROOT)
        for n, target in links(page):
            if re.match(r'^[a-z]+:', target):
                continue
            file, _, anchor = target.partition('#')
            dest = os.path.normpath(os.path.join(os.path.dirname(page), file)) if file else page
            if not os.path.exists(dest):
                broken.append(f'{rel}:{n}: {target}: no such file')
            elif anchor and dest.endswith('.md') and anchor not in anchors(dest):
                broken.append(f'{rel}:{n}: {target}: no heading #{anchor} there')
    book = os.path.join(ROOT, 'docs', 'src')
    listed = {os.path.normpath(os.path.join(book, t.partition('#')[0]))
              for _, t in links(os.path.join(book, 'SUMMARY.md'))}
    for folder, _, files in os.walk(book):
        for f in files:
            p = os.path.normpath(os.path.join(folder, f))
            if f.endswith('.md') and f != 'SUMMARY.md' and p not in listed:
                broken.append(f'docs/src/SUMMARY.md: {os.path.relpath(p, book)} is in no chapter')
    for b in broken:
        print(b)
    print(f'{len(pages())} pages checked, {len(broken)} broken link(s)')
    return 1 if broken else 0


if __name__ == '__main__':
    sys.exit(main())
