// The command line's passwords, found and redacted (core/secrets.hpp, issue 44).

#include "emcalign/core/secrets.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace emcalign::core {
namespace {

using ::testing::ElementsAre;
using ::testing::IsEmpty;
using ::testing::UnorderedElementsAre;

TEST(Secrets, PasswordsAreFoundWhereverTheyStandInAnArgument) {
  EXPECT_THAT(passwordsIn("postgresql://calib:secret@db/snd"), ElementsAre("secret"));
  EXPECT_THAT(passwordsIn("--conditions=postgres://u:p%40ss@db:5432/x"), UnorderedElementsAre("p%40ss", "p@ss"));
  // An '@' left unencoded is part of the password all the same.
  EXPECT_THAT(passwordsIn("@postgresql://u:pa@ss@db/x"), ElementsAre("pa@ss"));
  EXPECT_THAT(passwordsIn("postgresql://u@db/x?sslmode=require&password=hunter2"), ElementsAre("hunter2"));
  EXPECT_THAT(passwordsIn("host=db sslpassword='key pass' user=u"), ElementsAre("key pass"));
  EXPECT_THAT(passwordsIn("mysql://root:toor@localhost/db"), ElementsAre("toor"));
  // The parameter's name percent-encoded, or its '=' (libpq decodes both); a keyword string
  // with white space around '='.
  EXPECT_THAT(passwordsIn("postgresql://me@h/d?pass%77ord=hunter2secret"), ElementsAre("hunter2secret"));
  EXPECT_THAT(passwordsIn("postgresql://me@h/d?%70assword=hunter2secret"), ElementsAre("hunter2secret"));
  EXPECT_THAT(passwordsIn("postgresql://me@h/d?password%3Dhunter2secret"), ElementsAre("hunter2secret"));
  EXPECT_THAT(passwordsIn("host=h password = hunter2secret dbname=x"), ElementsAre("hunter2secret"));
  // No password: a user alone, a path with a colon, an e-mail address, a time.
  EXPECT_THAT(passwordsIn("postgresql://calib@db/snd"), IsEmpty());
  EXPECT_THAT(passwordsIn("runs/2026-12-04T10:00/ev.h5"), IsEmpty());
  EXPECT_THAT(passwordsIn("mail calib@snd.example 10:30"), IsEmpty());
  EXPECT_THAT(passwordsIn("postgresql://calib:@db/snd"), IsEmpty());
  // In a text (a plan's JSON), a URI ends with its line or its quoted string: a later '@' and
  // ':' are not its password.
  EXPECT_THAT(passwordsIn("\"postgresql://me@h:5432/x\",\n \"k\": \"a@b\"", true), IsEmpty());
  // In an argument, a '"' is part of it.
  EXPECT_THAT(passwordsIn("postgresql://u:A\"SEKRET@h/db"), ElementsAre("A\"SEKRET"));
  // A space in a password given raw is part of it.
  EXPECT_THAT(passwordsIn("postgresql://u:SEC RET@h/db"), ElementsAre("SEC RET"));
}

TEST(Secrets, RememberedPasswordsAreRedactedInEveryLine) {
  rememberPasswordsOf("postgresql://calib:Sekr3t%21@db/snd");
  rememberPasswordsOf("postgresql://u:Zq@db/x");  // too short to look for bare
  ASSERT_TRUE(passwordsRemembered());
  EXPECT_EQ(withoutPasswords("error: File does not exist: postgresql://calib:Sekr3t%21@db/snd"),
            "error: File does not exist: postgresql://calib:***@db/snd");
  EXPECT_EQ(withoutPasswords("libpq: password Sekr3t! refused"), "libpq: password *** refused");
  EXPECT_EQ(withoutPasswords("u:Zq@db, Zqa, aZq"), "u:***@db, Zqa, aZq");
  // Cut short by a message: its beginning before the ellipsis.
  EXPECT_EQ(withoutPasswords("--samples: 'postgresql://calib:Sekr3…' (49 characters)"),
            "--samples: 'postgresql://calib:***…' (49 characters)");
  EXPECT_EQ(withoutPasswords("'postgresql://calib:S…'"), "'postgresql://calib:***…'");
  EXPECT_EQ(withoutPasswords("a word Sek… cut"), "a word Sek… cut");
  EXPECT_TRUE(holdsPassword("x postgresql://a:b@c"));
  EXPECT_FALSE(holdsPassword("x postgresql://a@c"));
}

TEST(Secrets, ARedactingStreamWritesEveryLineWithoutTheRememberedPasswords) {
  rememberPasswordsOf("postgresql://calib:Str3amPw@db/snd");
  std::FILE* real = std::tmpfile();
  ASSERT_NE(real, nullptr);
  std::FILE* redacted = redactingStream(real);
  ASSERT_NE(redacted, nullptr);
  std::fputs("conditions ", redacted);  // a line written in pieces: redacted whole
  std::fputs("postgresql://calib:Str3am", redacted);
  std::fputs("Pw@db/snd: 3 tags\nsecond line, Str3amPw again\n", redacted);
  ASSERT_EQ(std::fclose(redacted), 0);
  std::rewind(real);
  std::string written(256, '\0');
  written.resize(std::fread(written.data(), 1, written.size(), real));
  std::fclose(real);
  EXPECT_EQ(written, "conditions postgresql://calib:***@db/snd: 3 tags\nsecond line, *** again\n");
}

}  // namespace
}  // namespace emcalign::core
