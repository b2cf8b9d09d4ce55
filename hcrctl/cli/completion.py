"""``hcrctl completion bash|zsh|fish``: the shell completion scripts, from the package itself.

Every script only calls ``hcrctl`` back on each TAB (Click's protocol:
``_HCRCTL_COMPLETE=<shell>_complete``), so subcommands, options, sensor names
and ports always come from the installed CLI and the scripts rarely change.
They are ours rather than Click's stock ones, for three reasons:

- bash splits words at the ``:`` of ``sim://`` (COMP_WORDBREAKS), so Click's
  script sent ``--port sim : // read co`` and nothing completed after a port
  URL. Ours joins those pieces again from COMP_LINE before calling hcrctl and
  trims what precedes the last colon from each answer, as bash-completion's
  ``__ltrim_colon_completions`` does, without needing bash-completion. It also
  runs on bash 3.2 (macOS), where Click's fails on ``compopt`` and ``nosort``.
- fish split each answer at every comma, so a description stopped at its
  first one ("Drive both motors (power"); ours splits at the first only.
- the text is the same whichever Click is installed (Click's templates and
  its escaping changed between 8.1 and 8.5).

The same classes answer ``_HCRCTL_COMPLETE=<shell>_source``: ``register()``
puts them in Click's table, so Click's own route prints these scripts too.
"""

from __future__ import annotations

import re
from typing import Any

import click
from click import shell_completion as sc

PROG = "hcrctl"

BASH = r"""# bash completion for %(prog_name)s: printed by `%(prog_name)s completion bash`; bash 3.2 or newer.
# Click's protocol (%(complete_var)s=bash_complete, COMP_WORDS, COMP_CWORD), with the words bash
# split at a COMP_WORDBREAKS character (the ':' of sim://) joined again from COMP_LINE.

if [ -z "${BASH_VERSION-}" ]; then
    echo "%(prog_name)s: this is the bash completion script; for zsh or fish: %(prog_name)s completion zsh|fish" >&2
    return 1 2>/dev/null || exit 1
fi
if ((BASH_VERSINFO[0] < 3 || (BASH_VERSINFO[0] == 3 && BASH_VERSINFO[1] < 2))); then
    echo "%(prog_name)s: completion needs bash 3.2 or newer, this is bash $BASH_VERSION" >&2
    return 1 2>/dev/null || exit 1
fi

%(complete_func)s_words() {
    # Sets %(complete_func)s_cword and the array %(complete_func)s_argv: COMP_WORDS, rejoined where
    # COMP_LINE has no blank between two of them. Without COMP_LINE, COMP_WORDS as they are.
    local line=${COMP_LINE-} blanks i j=-1
    %(complete_func)s_argv=()
    %(complete_func)s_cword=0
    if [[ -z $line ]]; then
        %(complete_func)s_argv=("${COMP_WORDS[@]}")
        %(complete_func)s_cword=$COMP_CWORD
        return
    fi
    for ((i = 0; i < ${#COMP_WORDS[@]}; i++)); do
        blanks=${line%%%%[![:blank:]]*}
        line=${line#"$blanks"}
        if ((j < 0)) || [[ -n $blanks || $line != "${COMP_WORDS[i]}"* ]]; then
            ((j++))
            %(complete_func)s_argv[j]=""
        fi
        %(complete_func)s_argv[j]+=${COMP_WORDS[i]}
        line=${line#"${COMP_WORDS[i]}"}
        if ((i == COMP_CWORD)); then
            %(complete_func)s_cword=$j
        fi
    done
}

%(complete_func)s() {
    local IFS=$'\n'
    local response completion type value cur trim=""
    local -a %(complete_func)s_argv
    local %(complete_func)s_cword

    %(complete_func)s_words
    cur=${%(complete_func)s_argv[%(complete_func)s_cword]}
    # bash replaces only the text after the word's last colon: answers must drop what precedes it.
    if [[ $cur == *:* && $COMP_WORDBREAKS == *:* ]]; then
        trim=${cur%%"${cur##*:}"}
    fi
    response=$(env COMP_WORDS="${%(complete_func)s_argv[*]}" COMP_CWORD=$%(complete_func)s_cword \
%(complete_var)s=bash_complete $1)

    for completion in $response; do
        IFS=',' read -r type value <<< "$completion"

        if [[ $type == 'dir' ]]; then
            COMPREPLY=()
            if ((BASH_VERSINFO[0] >= 4)); then compopt -o dirnames; fi
        elif [[ $type == 'file' ]]; then
            COMPREPLY=()
            if ((BASH_VERSINFO[0] >= 4)); then compopt -o default; fi
        elif [[ $type == 'plain' ]]; then
            COMPREPLY+=("${value#"$trim"}")
        fi
    done

    return 0
}

if ((BASH_VERSINFO[0] > 4 || (BASH_VERSINFO[0] == 4 && BASH_VERSINFO[1] >= 4))); then
    complete -o nosort -F %(complete_func)s %(prog_name)s
elif ((BASH_VERSINFO[0] == 4)); then
    complete -F %(complete_func)s %(prog_name)s
else
    # bash 3 has no compopt: readline's own file names stand in whenever hcrctl offers nothing.
    complete -o default -F %(complete_func)s %(prog_name)s
fi
"""

ZSH = r"""#compdef %(prog_name)s
# zsh completion for %(prog_name)s: printed by `%(prog_name)s completion zsh`; save it as _%(prog_name)s
# in a directory on $fpath, or source it. The function has the file's name, so once autoloaded
# it is what zsh calls on every later Tab (not this file's body again, which only registers it).

_%(prog_name)s() {
    local -a completions
    local -a completions_with_descriptions
    local -a response
    (( ! $+commands[%(prog_name)s] )) && return 1

    response=("${(@f)$(env COMP_WORDS="${words[*]}" COMP_CWORD=$((CURRENT-1)) \
%(complete_var)s=zsh_complete %(prog_name)s)}")

    for type key descr in ${response}; do
        if [[ "$type" == "plain" ]]; then
            if [[ "$descr" == "_" ]]; then
                completions+=("$key")
            else
                completions_with_descriptions+=("$key":"$descr")
            fi
        elif [[ "$type" == "dir" ]]; then
            _path_files -/
        elif [[ "$type" == "file" ]]; then
            _path_files -f
        fi
    done

    if [ -n "$completions_with_descriptions" ]; then
        _describe -V unsorted completions_with_descriptions -U
    fi

    if [ -n "$completions" ]; then
        compadd -U -V unsorted -a completions
    fi
}

if [[ $zsh_eval_context[-1] == loadautofunc ]]; then
    # autoload from fpath, call function directly
    _%(prog_name)s "$@"
else
    # eval/source/. command, register function for later
    compdef _%(prog_name)s %(prog_name)s
fi
"""

FISH = r"""# fish completion for %(prog_name)s: printed by `%(prog_name)s completion fish`.
# Each answer is TYPE,VALUE<tab>DESCRIPTION: split at the first comma only, so a
# description keeps its own commas.

function %(complete_func)s
    set -l response (env %(complete_var)s=fish_complete COMP_WORDS=(commandline -cp) \
COMP_CWORD=(commandline -t) %(prog_name)s)

    for completion in $response
        set -l metadata (string split -m 1 -- "," $completion)

        if test "$metadata[1]" = "dir"
            __fish_complete_directories $metadata[2]
        else if test "$metadata[1]" = "file"
            __fish_complete_path $metadata[2]
        else if test "$metadata[1]" = "plain"
            echo $metadata[2]
        end
    end
end

complete --no-files --command %(prog_name)s --arguments "(%(complete_func)s)"
"""

#: shell -> its script, %-formatted with ``source_vars``.
TEMPLATES = {"bash": BASH, "zsh": ZSH, "fish": FISH}


def source_vars(prog: str = PROG) -> dict[str, str]:
    """The names a script uses, derived from the program name as Click derives them."""
    safe = re.sub(r"\W", "", prog.replace("-", "_"), flags=re.ASCII)
    return {
        "complete_func": f"_{safe}_completion",
        "complete_var": f"_{prog}_COMPLETE".replace("-", "_").upper(),
        "prog_name": prog,
    }


def script(shell: str, prog: str = PROG) -> str:
    """The completion script for ``shell`` (bash, zsh or fish)."""
    return TEMPLATES[shell] % source_vars(prog)


def one_line(text: str | None) -> str:
    """A help text as one line: the scripts read one answer per line (zsh: three lines per answer)."""
    return " ".join((text or "").split())


class Bash(sc.BashComplete):
    """Click's bash protocol with our script; no ``bash --version`` probe (the script checks its bash)."""

    def source(self) -> str:
        return script("bash", self.prog_name)


class Zsh(sc.ZshComplete):
    """Click's zsh protocol with our script: help on one line, a colon in a described value escaped."""

    def source(self) -> str:
        return script("zsh", self.prog_name)

    def format_completion(self, item: sc.CompletionItem[Any]) -> str:
        help_ = one_line(item.help) or "_"
        # _describe splits value from help at the first unescaped colon; compadd (no help) takes it as is.
        value = str(item.value).replace(":", r"\:") if help_ != "_" else str(item.value)
        return f"{item.type}\n{value}\n{help_}"


class Fish(sc.FishComplete):
    """Click's fish protocol with our script (split at the first comma): help on one line, no tabs."""

    def source(self) -> str:
        return script("fish", self.prog_name)

    def format_completion(self, item: sc.CompletionItem[Any]) -> str:
        help_ = one_line(item.help)
        return f"{item.type},{item.value}\t{help_}" if help_ else f"{item.type},{item.value}"


CLASSES: dict[str, type[sc.ShellComplete]] = {"bash": Bash, "zsh": Zsh, "fish": Fish}


def register() -> None:
    """Make Click's ``_HCRCTL_COMPLETE=<shell>_source|_complete`` use these classes."""
    for name, cls in CLASSES.items():
        sc.add_completion_class(cls, name)


@click.command(name="completion")
@click.argument("shell", type=click.Choice(list(TEMPLATES)), metavar="SHELL")
def completion(shell: str) -> None:
    """Print the completion script for SHELL (bash, zsh or fish).

    The script calls hcrctl back on each Tab, so it stays right as hcrctl
    changes. Where each one goes:

    \b
    bash  hcrctl completion bash > ~/.local/share/bash-completion/completions/hcrctl
          (that directory is read by the bash-completion package); without it,
          save the script anywhere and source it from ~/.bashrc
    zsh   hcrctl completion zsh > ~/.zfunc/_hcrctl
          with fpath+=(~/.zfunc) before compinit in ~/.zshrc
    fish  hcrctl completion fish > ~/.config/fish/completions/hcrctl.fish
    """
    click.echo(script(shell), nl=False)
