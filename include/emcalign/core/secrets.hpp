#pragma once
// Secrets never leave the process (docs/conventions.md): a password written into the command
// line — a URI's user:password@, a password= parameter, wherever the argument stands, a
// misplaced one included — is remembered when the process starts, and every line it prints or
// file it writes shows "***" instead. The conditions database's own addresses are redacted by
// conddb::DatabaseAddress as well; this catches the rest (a URI given where a file was expected).

#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace emcalign::core {

/// %XX decoded, as libpq decodes the parts of a URI; a malformed escape is kept as written.
std::string percentDecoded(std::string_view s);

/// The passwords `text` holds: for every "scheme://user:password@…" the password (as written and
/// percent-decoded); the value of every "password=" (any case, also
/// sslpassword=), up to '&', white space or the end. Empty when it holds none.
/// `withinText`: `text` is a text (a plan's JSON), where a URI also ends with its line or its
/// quoted string; else an argument, whose URI runs to its end ('"' may be in a password).
std::vector<std::string> passwordsIn(std::string_view text, bool withinText = false);

/// Remembers the passwords of `text` (the command line's arguments, one by one).
void rememberPasswordsOf(std::string_view text);
/// Whether any password is remembered.
bool passwordsRemembered();
/// withoutPasswords, and the passwords `text` holds itself (a text read from a file, to be
/// stored: a tag's description from an edited plan).
std::string withoutAnyPassword(std::string text);
/// Whether `text` holds a password (passwordsIn not empty).
bool holdsPassword(std::string_view text, bool withinText = false);
/// `text` with every remembered password as "***" (longest first; one of fewer than 4
/// characters only where it follows a ':' or a '=', as in "user:pw@" or "password=pw").
std::string withoutPasswords(std::string text);

/// A stream writing to `real` with every remembered password as "***", a line at a time (a
/// password never straddles two writes; up to 1 MiB a line): standard output of a process whose
/// command line holds a password. Null when none can be made (then `real` is used as it is).
std::FILE* redactingStream(std::FILE* real);

}  // namespace emcalign::core
